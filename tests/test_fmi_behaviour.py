"""What hosts rely on, through the FMI C API of the built FMUs (fmpy's FMU2Slave, raw status codes).

Several instances in one process; two versions of one FMU in one process; 200 instantiate/free
cycles (and failing ones) without a crash or growing memory; reset; get/set FMU state; model
errors as fmi2Discard with the cause logged; parameter errors at initialisation; the Python
requirements each FMU carries.
"""

from __future__ import annotations

import ast
import ctypes
import functools
import importlib.metadata
import json
import re
import shutil
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import numpy as np
import pytest

import mast.core.build as build
from fmus.common.block import Block
from fmus.common.parameters import Param
from mast.core.build import FMU_REQUIREMENTS, FMUS, build_fmu

ROOT = Path(__file__).resolve().parents[1]
OK, WARNING, DISCARD, ERROR, FATAL = range(5)
IDENTIFIERS = [
    spec.model_identifier
    for spec in FMUS
    if spec.model_identifier in ("MastActuator", "MastMechanism", "MastController", "MastTrajectory")
]


@functools.lru_cache(maxsize=None)
def model_description(fmu: str):
    from fmpy import read_model_description

    return read_model_description(fmu)


class Instance:
    """One FMU instance through fmpy, with its log and the raw status of each call."""

    def __init__(self, fmu: Path, name: str, unzip: Path | None = None) -> None:
        from fmpy import extract
        from fmpy.fmi2 import (
            FMU2Slave,
            calloc,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
            free,
        )

        self.md = model_description(str(fmu))
        self.unzip = unzip or Path(extract(str(fmu)))
        self.log: list[tuple[int, str]] = []
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.inputs = [v.name for v in self.md.modelVariables if v.causality == "input"]
        self.outputs = [v.name for v in self.md.modelVariables if v.causality == "output"]
        self.slave = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=str(self.unzip),
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )

        def logger(_env, _name, status, _category, message):
            self.log.append((status, (message or b"").decode(errors="replace")))

        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self.slave.instantiate(callbacks=self._callbacks, loggingOn=True)
        self.dll, self.c = self.slave.dll, self.slave.component

    def start(self, parameters: dict | None = None, t0: float = 0.0) -> int:
        """setupExperiment, enterInitializationMode, parameters (a str by setString, else setReal),
        exitInitializationMode: the last status."""
        self.slave.setupExperiment(startTime=t0)
        self.slave.enterInitializationMode()
        for name, value in (parameters or {}).items():
            setter = self.slave.setString if isinstance(value, str) else self.slave.setReal
            setter([self.vr[name]], [value])
        return self.dll.fmi2ExitInitializationMode(self.c)

    def set(self, **values: float) -> None:
        self.slave.setReal([self.vr[n] for n in values], list(values.values()))

    def get(self, names=None) -> list[float]:
        return self.slave.getReal([self.vr[n] for n in (names or self.outputs)])

    def step(self, t: float, h: float) -> int:
        return self.dll.fmi2DoStep(self.c, t, h, 1)

    def close(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()
        self._callbacks = None  # the logger closure refers to self: let reference counting free both


def drive(inst: Instance, first: int, n: int, h: float = 1e-4, seed: float = 0.0) -> np.ndarray:
    """Steps first .. first + n - 1 (t = k h) with smooth, instance-specific inputs; the outputs after each."""
    rows = []
    for k in range(first, first + n):
        t = k * h
        if inst.inputs:
            inst.set(**{name: _input(name, t, seed) for name in inst.inputs})
        assert inst.step(t, h) == OK, inst.log[-3:]
        rows.append(inst.get())
    return np.array(rows)


def _input(name: str, t: float, seed: float) -> float:
    """Inputs each FMU accepts: current commands, forces, carriage motion, a pose near home, the condensed coupling's
    masses and drive forces."""
    wave = np.sin(2 * np.pi * (3.0 + seed) * t)
    base = {"i_cmd": 4.0 * wave, "F": 6.0 + seed, "z_cmd": 0.405147 + 0.003 * wave, "psi_cmd": 0.0, "theta_cmd": 0.0}
    if name in base:
        return float(base[name])
    if name.startswith("m_drive") or name == "M_carried":  # masses of the condensed coupling: >= 0
        return 5.9 + float(wave)
    if name.startswith("F_drive"):
        return 20.0 * float(wave)
    if name.startswith("rho_dot"):
        return 0.01 * float(np.cos(2 * np.pi * 3.0 * t))
    if name.startswith("rho_ddot"):
        return -0.2 * wave
    if name.startswith("rho"):
        return 0.15 + 0.002 * wave
    return 0.1 * wave  # omega_m_k


# -- what each FMU carries ---------------------------------------------------------------------------
def _imports(package: Path) -> set[str]:
    names = set()
    for file in package.rglob("*.py"):
        for node in ast.walk(ast.parse(file.read_text())):
            if isinstance(node, ast.Import):
                names |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
    return names


def _requirement(text: str) -> str:
    """A requirement as text, spaces and the marker's quotes normalised ("tomli>=1.1;python_version<'3.11'")."""
    return text.replace(" ", "").replace('"', "'")


def test_each_fmu_carries_the_requirements_of_its_code_for_pythonfmu_deploy(built):
    third_party = _imports(ROOT / "fmus") - set(sys.stdlib_module_names) - {"__future__", "pythonfmu", "pythonfmu3"}
    required = {re.split(r"[<>=!~;\s]", r, maxsplit=1)[0] for r in FMU_REQUIREMENTS}
    assert third_party == required, "fmus/ imports and mast.core.build.FMU_REQUIREMENTS disagree"
    # name, versions and marker (python_version ...) as the project's own dependency: pip honours the marker
    project = {_requirement(r) for r in importlib.metadata.requires("mast-cosim")}
    differ = [r for r in FMU_REQUIREMENTS if _requirement(r) not in project]
    assert not differ, f"FMU requirements {differ} differ from the project's own dependencies (markers included)"
    for identifier in IDENTIFIERS:
        with zipfile.ZipFile(built / "fmus" / f"{identifier}.fmu") as z:
            assert z.read("resources/requirements.txt").decode().splitlines() == list(FMU_REQUIREMENTS)
            names = z.namelist()
        assert any(n.startswith("resources/pythonfmu/") for n in names)  # pythonfmu itself travels inside


def test_pythonfmu_deploy_installs_from_the_bundled_requirements(built):
    """`pythonfmu deploy` runs pip on resources/requirements.txt (here everything is present already)."""
    proc = subprocess.run(
        [sys.executable, "-m", "pythonfmu", "deploy", "-f", str(built / "fmus" / "MastTrajectory.fmu")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "numpy" in proc.stdout and "scipy" in proc.stdout


def test_model_descriptions_declare_what_the_fmus_do(built):
    for identifier in IDENTIFIERS:
        from fmpy import read_model_description

        cs = read_model_description(str(built / "fmus" / f"{identifier}.fmu")).coSimulation
        assert cs.canGetAndSetFMUstate and not cs.needsExecutionTool and not cs.canBeInstantiatedOnlyOncePerProcess


# -- several instances, several versions ---------------------------------------------------------------
def test_instances_of_one_fmu_in_one_process_stay_independent(built):
    fmu = built / "fmus" / "MastActuator.fmu"
    solo = []
    for seed in (0.0, 1.0, 2.0):
        inst = Instance(fmu, f"solo{seed}")
        assert inst.start({"tau_c": 0.0718} if seed == 1.0 else None) == OK
        solo.append(drive(inst, 0, 300, seed=seed))
        inst.close()
    together = [Instance(fmu, f"axis{k}") for k in range(3)]
    for k, inst in enumerate(together):
        assert inst.start({"tau_c": 0.0718} if k == 1 else None) == OK
    runs = [[], [], []]
    for block in range(6):  # interleaved: 50 steps each, in turn
        for k, inst in enumerate(together):
            runs[k].append(drive(inst, block * 50, 50, seed=float(k)))
    for inst in together:
        inst.close()
    for k in range(3):
        np.testing.assert_array_equal(np.vstack(runs[k]), solo[k])
    assert not np.array_equal(solo[0], solo[1])  # the parameter and the inputs made a difference


def test_two_versions_of_one_fmu_in_one_process_each_run_their_own_code(built, tmp_path, monkeypatch):
    """Same model identifier, same entry script name in pythonfmu's eyes, different code: no collision."""
    changed = tmp_path / "fmus"
    shutil.copytree(ROOT / "fmus", changed, ignore=shutil.ignore_patterns("__pycache__"))
    model = changed / "trajectory" / "model.py"
    source = model.read_text()
    marker = "self.values[:] = [h + a * s for h, a in zip(self._home, self._amplitude)]"
    assert marker in source
    model.write_text(source.replace(marker, marker.replace("h + a * s", "h + a * s + 1.0")))
    spec = next(s for s in FMUS if s.model_identifier == "MastTrajectory")
    monkeypatch.setattr(build, "FMUS_SRC", changed)
    other = build_fmu(spec, tmp_path / "other")
    monkeypatch.undo()

    def first_output(fmu: Path, name: str) -> float:
        inst = Instance(fmu, name)
        assert inst.start() == OK
        value = inst.get(["z_cmd"])[0]
        inst.close()
        return value

    original = built / "fmus" / "MastTrajectory.fmu"
    for _ in range(2):  # each loaded and instantiated again after the other
        assert first_output(other, "changed") == pytest.approx(first_output(original, "original") + 1.0)
    entries = set()
    for fmu in (original, other):
        with zipfile.ZipFile(fmu) as z:
            entries.add(z.read("resources/slavemodule.txt").decode().strip())
    assert len(entries) == 2 and all(e.startswith("mast_trajectory_") for e in entries)


def test_same_entry_and_package_names_would_collide(built, tmp_path, monkeypatch):
    """The failure the unique names prevent: with one name for both, the second FMU runs the first one's code."""
    changed = tmp_path / "fmus"
    shutil.copytree(ROOT / "fmus", changed, ignore=shutil.ignore_patterns("__pycache__"))
    model = changed / "trajectory" / "model.py"
    model.write_text(model.read_text().replace("h + a * s for h, a", "h + a * s + 1.0 for h, a"))
    spec = next(s for s in FMUS if s.model_identifier == "MastTrajectory")
    name = f"collide{tmp_path.name.replace('-', '_')}"
    monkeypatch.setattr(build, "_source_hash", lambda extra: name)
    first = build_fmu(spec, tmp_path / "first")
    monkeypatch.setattr(build, "FMUS_SRC", changed)
    second = build_fmu(spec, tmp_path / "second")
    values = []
    for fmu, label in ((first, "a"), (second, "b")):
        inst = Instance(fmu, label)
        inst.start()
        values.append(inst.get(["z_cmd"])[0])
        inst.close()
    assert values[0] == values[1]  # the second FMU ran the first one's code: hence mast_<pkg>_<hash>


# -- life cycle: cycles, failures, reset, state ----------------------------------------------------------
CYCLES = """
import json, sys, gc
sys.path.insert(0, {tests!r})
from test_fmi_behaviour import Instance, drive, OK, DISCARD
def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096
fmus, n = {fmus!r}, {n}
report, unzipped = {{}}, {{}}
for name, fmu in fmus.items():
    for k in range(n):
        if k == n // 2:  # after the allocator has warmed up
            gc.collect(); before = rss(); path = len(sys.path)
        inst = Instance(fmu, f"i{{k}}", unzipped.get(name))
        unzipped[name] = inst.unzip
        assert inst.start() == OK, inst.log
        drive(inst, 0, 5)
        inst.close()
    gc.collect()
    report[name] = {{"growth_per_cycle": (rss() - before) / (n - n // 2), "sys_path_growth": len(sys.path) - path}}
# failing instances, each terminated and freed: a bad parameter (logged at exitInitializationMode, then
# every doStep refused) and a doStep on a non-finite input
failures = {{"parameter": 0, "step": 0}}
for k in range(n):
    inst = Instance(fmus["MastTrajectory"], f"bad{{k}}", unzipped["MastTrajectory"])
    assert inst.start({{"frequency": -1.0}}) == OK
    failures["parameter"] += inst.step(0.0, 1e-4) == DISCARD
    inst.close()
    inst = Instance(fmus["MastMechanism"], f"nan{{k}}", unzipped["MastMechanism"])
    assert inst.start() == OK
    inst.set(rho_1=float("nan"))
    failures["step"] += inst.step(0.0, 1e-3) == DISCARD
    inst.close()
report["failures"] = failures
print(json.dumps(report))
"""


def test_200_instantiate_free_cycles_and_200_failing_instances_without_crash_or_growing_memory(built):
    fmus = {identifier: str(built / "fmus" / f"{identifier}.fmu") for identifier in IDENTIFIERS}
    script = CYCLES.format(tests=str(Path(__file__).parent), fmus=fmus, n=200)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, f"exit {proc.returncode}: {proc.stderr[-3000:]}"
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report.pop("failures") == {"parameter": 200, "step": 200}
    for fmu, figures in report.items():
        # measured 1-2 KiB per cycle: ~1 KiB are 14 Python objects pythonfmu 0.7.0 creates and never
        # releases at each instantiation (docs/using-the-fmus.md); a block or instance kept alive costs far more
        assert figures["growth_per_cycle"] < 8 * 1024, (fmu, figures)
        assert figures["sys_path_growth"] == 0, (fmu, figures)


def test_a_model_failure_is_a_refused_step_that_names_the_cause(built):
    inst = Instance(built / "fmus" / "MastActuator.fmu", "axis2")
    assert inst.start() == OK
    assert inst.step(0.0, 1e-4) == OK
    inst.set(F=float("inf"))
    assert inst.step(1e-4, 1e-4) == DISCARD
    status, message = inst.log[-1]
    assert status == ERROR and "doStep at t=0.0001 s" in message and "input 'F' = inf" in message
    assert "axis2" in message and "not finite" in message
    assert inst.slave.getBooleanStatus(3)  # fmi2Terminated: the FMU asks the host to stop
    inst.close()  # still usable for terminate and free


def test_a_bad_parameter_is_named_at_initialization_and_refuses_every_step(built):
    inst = Instance(built / "fmus" / "MastMechanism.fmu", "mechanism")
    assert inst.start({"m_platform": -1.0}) == OK  # see fmus/common/fmi.py: a status pythonfmu cannot give
    status, message = next((s, m) for s, m in inst.log if "exitInitializationMode" in m)
    assert status == ERROR and "m_platform" in message and "-1" in message and "(0, inf) kg" in message
    for k in range(3):
        assert inst.step(k * 1e-3, 1e-3) == DISCARD
        assert "did not initialise" in inst.log[-1][1] and "m_platform" in inst.log[-1][1]
    inst.close()


def test_outputs_read_during_initialization_tolerate_inputs_not_set_yet(built):
    """A host iterating to a consistent start may read outputs while the inputs are not consistent yet."""
    inst = Instance(built / "fmus" / "MastController.fmu", "controller")
    inst.slave.setupExperiment(startTime=0.0)
    inst.slave.enterInitializationMode()
    inst.set(z_cmd=0.4, psi_cmd=1.3)  # a tilt the mechanism cannot reach
    vr, value = (ctypes.c_uint * 1)(inst.vr["rho_cmd_1"]), (ctypes.c_double * 1)()
    assert inst.dll.fmi2GetReal(inst.c, vr, 1, value) == OK
    status, message = inst.log[-1]
    assert status == WARNING and "inverse kinematics of the pose command" in message and "psi = 1.3 rad" in message
    inst.set(z_cmd=0.4051470164434615, psi_cmd=0.0, **{f"rho_{k}": 0.15 for k in (1, 2, 3)})
    assert inst.dll.fmi2ExitInitializationMode(inst.c) == OK
    assert not [m for s, m in inst.log if s >= ERROR]
    assert inst.get(["rho_cmd_1"])[0] == pytest.approx(0.15, abs=1e-9)
    inst.close()


def test_reset_returns_to_the_instantiated_state(built):
    inst = Instance(built / "fmus" / "MastActuator.fmu", "axis")
    default_tau_c = inst.get(["tau_c"])[0]
    assert inst.start({"tau_c": 0.0718}) == OK
    first = drive(inst, 0, 200)
    inst.slave.terminate()
    assert inst.dll.fmi2Reset(inst.c) == OK
    assert inst.get(["tau_c"])[0] == default_tau_c  # parameters back to their start values
    assert inst.start({"tau_c": 0.0718}) == OK
    np.testing.assert_array_equal(drive(inst, 0, 200), first)
    inst.close()


@pytest.mark.parametrize("identifier", IDENTIFIERS)
def test_a_restored_state_reproduces_the_same_continuation(built, identifier):
    inst = Instance(built / "fmus" / f"{identifier}.fmu", "x")
    assert inst.start() == OK
    h = 1e-3 if identifier == "MastMechanism" else 1e-4
    drive(inst, 0, 50, h)
    state = inst.slave.getFMUstate()
    ahead = drive(inst, 50, 100, h)
    inst.slave.setFMUstate(state)
    again = drive(inst, 50, 100, h)
    np.testing.assert_array_equal(again, ahead)
    assert np.ptp(ahead, axis=0).max() > 0  # the continuation moved
    # a state is independent of what happened after it was taken: roll back twice
    inst.slave.setFMUstate(state)
    np.testing.assert_array_equal(drive(inst, 50, 100, h), ahead)
    inst.slave.freeFMUstate(state)
    inst.close()


def test_state_taken_before_initialization_and_after_a_parameter_change(built):
    inst = Instance(built / "fmus" / "MastActuator.fmu", "axis")
    inst.slave.setupExperiment(startTime=0.0)
    inst.slave.enterInitializationMode()
    early = inst.slave.getFMUstate()  # no block yet
    inst.set(tau_c=0.0718)
    assert inst.dll.fmi2ExitInitializationMode(inst.c) == OK
    with_friction = drive(inst, 0, 100)
    inst.slave.setFMUstate(early)  # back in initialization mode, default parameters
    assert inst.get(["tau_c"])[0] != 0.0718
    assert inst.dll.fmi2ExitInitializationMode(inst.c) == OK
    default = drive(inst, 0, 100)
    assert not np.array_equal(default, with_friction)
    fresh = Instance(built / "fmus" / "MastActuator.fmu", "fresh", inst.unzip)
    assert fresh.start() == OK
    np.testing.assert_array_equal(drive(fresh, 0, 100), default)
    inst.slave.freeFMUstate(early)
    for i in (inst, fresh):
        i.close()


def test_a_foreign_state_is_refused_with_error_and_the_instance_survives(built):
    """fmi2SetFMUstate with another FMU's state raises inside the slave: pythonfmu reports fmi2Fatal and,
    without mast's compensation (fmus/common/slave.py), would release the instance twice; the C front
    says fmi2Error, and the instance goes on stepping. 100 rounds: no crash."""
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_fmi_behaviour import Instance, drive, OK, ERROR
        unzip = {{}}
        for k in range(100):
            a = Instance({str(built / "fmus" / "MastActuator.fmu")!r}, f"a{{k}}", unzip.get("a"))
            t = Instance({str(built / "fmus" / "MastTrajectory.fmu")!r}, f"t{{k}}", unzip.get("t"))
            unzip.update(a=a.unzip, t=t.unzip)
            assert a.start() == OK and t.start() == OK
            foreign = t.slave.getFMUstate()
            assert a.dll.fmi2SetFMUstate(a.c, foreign) == ERROR
            assert a.log[-1][0] == ERROR and "not an FMU state of MastActuator" in a.log[-1][1], a.log[-3:]
            drive(a, 0, 2)  # still usable
            t.slave.freeFMUstate(foreign)
            a.close(); t.close()
        print("survived")
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0 and proc.stdout.strip().endswith("survived"), proc.stderr[-3000:]


# -- the FMI state machine -------------------------------------------------------------------------------
def _real(inst: Instance, function: str, name_or_vr, value: float = 0.0) -> int:
    """The raw status of fmi2SetReal or fmi2GetReal on one variable (a name, or a bare value reference)."""
    vr = (ctypes.c_uint * 1)(inst.vr[name_or_vr] if isinstance(name_or_vr, str) else name_or_vr)
    buf = (ctypes.c_double * 1)(value)
    return getattr(inst.dll, function)(inst.c, vr, 1, buf)


@pytest.mark.parametrize(
    "case",
    [
        "exit before enter",
        "parameter after initialization",
        "output",
        "unknown reference",
        "wrong type",
        "step after terminate",
        "step before initialization",
        "enter twice",
    ],
)
def test_illegal_calls_return_error_name_the_fault_and_change_nothing(built, case):
    """FMI 2.0 section 4.3: a call its state does not allow, a set the variable does not allow, an unknown
    value reference: fmi2Error with one message (status Error) naming the fault, and nothing changes: the
    following legal calls run as on an instance that never saw it."""
    inst = Instance(built / "fmus" / "MastActuator.fmu", "axis")
    fresh = Instance(built / "fmus" / "MastActuator.fmu", "fresh", inst.unzip)

    def refused(status: int, *words: str) -> None:
        assert status == ERROR, inst.log[-2:]
        assert inst.log[-1][0] == ERROR and all(w in inst.log[-1][1] for w in words), inst.log[-2:]
        assert not [m for s, m in inst.log if s == FATAL]  # pythonfmu's own Fatal report is not passed on

    if case == "exit before enter":
        refused(inst.dll.fmi2ExitInitializationMode(inst.c), "exitInitializationMode", "not allowed in instantiated")
    elif case == "step before initialization":
        refused(inst.step(0.0, 1e-4), "doStep", "not allowed in instantiated")
    elif case == "enter twice":
        inst.slave.setupExperiment(startTime=0.0)
        inst.slave.enterInitializationMode()
        refused(
            inst.dll.fmi2EnterInitializationMode(inst.c),
            "enterInitializationMode",
            "not allowed in initialization mode",
        )
    if case == "enter twice":
        inst.set(tau_c=0.0718)
        assert inst.dll.fmi2ExitInitializationMode(inst.c) == OK
    else:
        assert inst.start({"tau_c": 0.0718}) == OK
    assert fresh.start({"tau_c": 0.0718}) == OK
    np.testing.assert_array_equal(drive(inst, 0, 3), drive(fresh, 0, 3))
    first = 3
    if case == "parameter after initialization":  # was: OK, then every doStep Discard
        refused(
            _real(inst, "fmi2SetReal", "tau_c", 0.05),
            "setReal",
            "parameter 'tau_c' is fixed",
            "before exitInitializationMode",
            "step mode",
        )
        assert inst.get(["tau_c"]) == [0.0718]
    elif case == "output":
        refused(_real(inst, "fmi2SetReal", "tau_m", 1.0), "'tau_m' is output", "only inputs and parameters")
    elif case == "unknown reference":
        refused(_real(inst, "fmi2GetReal", 4711), "getReal", "value reference 4711 is not a variable of")
    elif case == "wrong type":
        vr, value = (ctypes.c_uint * 1)(inst.vr["tau_c"]), (ctypes.c_int * 1)(1)
        refused(inst.dll.fmi2SetInteger(inst.c, vr, 1, value), "setInteger", "'tau_c'", "is of type Real, not Integer")
    elif case == "step after terminate":
        assert inst.dll.fmi2Terminate(inst.c) == OK
        refused(inst.step(3e-4, 1e-4), "doStep", "not allowed in terminated")
        assert _real(inst, "fmi2GetReal", "rho") == OK  # a legal call after it
        fresh.slave.terminate()
        for i in (inst, fresh):  # and a reset, to run again
            assert i.dll.fmi2Reset(i.c) == OK and i.start({"tau_c": 0.0718}) == OK
        first = 0
    np.testing.assert_array_equal(drive(inst, first, 20), drive(fresh, first, 20))
    for i in (inst, fresh):
        i.close()


def _slave_of(inst: Instance):
    """The Python slave object behind an instance (pythonfmu runs it in this interpreter)."""
    import gc

    identifier = inst.md.coSimulation.modelIdentifier
    found = [
        o for o in gc.get_objects() if type(o).__name__ == identifier and o.instance_name == inst.slave.instanceName
    ]
    assert len(found) == 1, found
    return found[0]


def test_a_failure_nobody_foresaw_is_fatal_and_the_instance_refuses_every_later_call(built):
    """An exception other than an illegal call (here: a defect injected into the glue, on a path the C front
    forwards: getReal of a parameter; the inputs and outputs it answers from its buffer) is fmi2Fatal, logged
    with status Fatal, and every later call is refused with fmi2Fatal until fmi2Reset."""
    inst = Instance(built / "fmus" / "MastActuator.fmu", "broken")
    assert inst.start() == OK
    drive(inst, 0, 3)

    class Defective(frozenset):  # the value references' check, on every path of getReal (fast_get too)
        def issuperset(self, *_):
            raise ZeroDivisionError("injected")

    _slave_of(inst)._io_refs = Defective()
    assert _real(inst, "fmi2GetReal", "tau_c") == FATAL
    assert (FATAL, "getReal: ZeroDivisionError: injected") in inst.log
    for status in (inst.step(3e-4, 1e-4), _real(inst, "fmi2SetReal", "i_cmd", 1.0), inst.dll.fmi2Terminate(inst.c)):
        assert status == FATAL and "failed earlier (getReal: ZeroDivisionError" in inst.log[-1][1], inst.log[-2:]
    assert inst.dll.fmi2Reset(inst.c) == OK  # fmi2Reset: a fresh slave (without the defect), usable again
    assert inst.start() == OK
    drive(inst, 0, 3)
    inst.close()


def test_without_the_c_front_an_illegal_call_is_fatal_and_the_instance_refuses_what_follows(built, tmp_path):
    """An FMU with pythonfmu's own binary (a build without a C compiler) cannot say fmi2Error: it says
    fmi2Fatal and keeps to it (every later call refused), as FMI requires after Fatal."""
    from fmpy import extract

    unzip = Path(extract(str(built / "fmus" / "MastActuator.fmu"), str(tmp_path / "fmu")))
    folder = unzip / "binaries" / "linux64"
    (folder / "MastActuator.pythonfmu.so").replace(folder / "MastActuator.so")
    inst = Instance(built / "fmus" / "MastActuator.fmu", "plain", unzip)
    assert inst.step(0.0, 1e-4) == FATAL
    assert (FATAL, "doStep: not allowed in instantiated (allowed in step mode)") in inst.log
    assert inst.dll.fmi2SetupExperiment(inst.c, 0, 0.0, 0.0, 0, 0.0) == FATAL and "failed earlier" in inst.log[-2][1]
    inst.slave.freeInstance()


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_the_build_falls_back_to_pythonfmus_binary_without_a_c_compiler(monkeypatch, tmp_path, fmi_version):
    import mast.core.native.compiler as toolchain

    if fmi_version == 3:
        pytest.importorskip("pythonfmu3")

    def no_compiler(platform: str = "linux64"):
        raise toolchain.NativeBuildError("no C compiler here (test)")

    monkeypatch.setattr(toolchain, "c_compiler", no_compiler)
    build._compiled_front.cache_clear()
    try:
        assert (
            f"fmi{fmi_version}Fatal instead of fmi{fmi_version}Error (no C compiler here (test))"
            in build.front_note(fmi_version)
        )
        spec = next(s for s in FMUS if s.model_identifier == "MastTrajectory")
        fmu = (build_fmu if fmi_version == 2 else build.build_fmu3)(spec, tmp_path)
    finally:
        build._compiled_front.cache_clear()
    binary = build.FRONT_BINARY[fmi_version].format("MastTrajectory")
    with zipfile.ZipFile(fmu) as z:
        names = z.namelist()
    assert binary in names and binary.replace(".so", ".pythonfmu.so") not in names
    from fmpy import simulate_fmu

    result = simulate_fmu(str(fmu), stop_time=0.01, output_interval=0.01)  # pythonfmu's binary runs it
    assert result["z_cmd"][-1] > 0.4


def test_legal_sets_in_each_state(built):
    """Parameters before exitInitializationMode, inputs until terminate; gets in every state."""
    inst = Instance(built / "fmus" / "MastActuator.fmu", "axis")
    assert _real(inst, "fmi2SetReal", "tau_c", 0.0718) == OK  # instantiated: a parameter
    inst.slave.setupExperiment(startTime=0.0)
    inst.slave.enterInitializationMode()
    assert _real(inst, "fmi2SetReal", "tau_c", 0.0718) == OK  # initialization mode: a parameter
    assert _real(inst, "fmi2SetReal", "i_cmd", 1.0) == OK  # and an input
    assert inst.dll.fmi2ExitInitializationMode(inst.c) == OK
    assert _real(inst, "fmi2SetReal", "i_cmd", 2.0) == OK  # step mode: an input
    assert inst.step(0.0, 1e-4) == OK and _real(inst, "fmi2GetReal", "tau_c") == OK
    assert inst.dll.fmi2Terminate(inst.c) == OK
    assert _real(inst, "fmi2GetReal", "tau_m") == OK  # terminated: gets still answer
    assert not [m for st, m in inst.log if st >= ERROR], inst.log
    inst.slave.freeInstance()


class Halver(Block):
    """A block with one direct-feedthrough output (y = k b, evaluated at the communication point) and one that
    changes only in doStep (z): the FMI wrappers' feedthrough, tested on a block of its own."""

    INPUTS = ("a", "b")
    OUTPUTS = ("y", "z")
    PARAMETERS = (Param("k", "1", "gain"),)
    FEEDTHROUGH = {"y": ("b",)}

    def initialize(self, t0):
        self.evaluate()

    def evaluate(self):
        if self.values[1] > 100.0:
            raise ValueError("b above 100 (the '%' in this message reaches an FMI 3.0 host as it is)")
        self.values[2] = self.params["k"] * self.values[1]

    def do_step(self, t, h):
        self.values[3] += h


def test_a_feedthrough_output_follows_its_input_and_is_declared_in_the_model_structure():
    """Block.FEEDTHROUGH through the FMI 2.0 wrapper, in process: after setReal of the input in step mode
    the output is the model's evaluation of it (no doStep); the modelDescription lists the dependency; a
    failed evaluation is logged and refuses the next step."""
    from fmus.common.fmi import BlockSlave

    class HalverSlave(BlockSlave):
        block_class = Halver

    slave = HalverSlave(instance_name="halver")
    structure = {
        u.get("index"): u.get("dependencies") for u in slave.to_xml().iterfind("ModelStructure/Outputs/Unknown")
    }
    names = [v.name for v in slave.vars.values()]
    assert {names[int(i) - 1]: dep for i, dep in structure.items()} == {"y": str(names.index("b") + 1), "z": ""}
    slave.setup_experiment(0.0, None, None)
    slave.enter_initialization_mode()
    slave.set_real([names.index("k")], [0.5])
    slave.exit_initialization_mode()
    slave.set_real([1], [8.0])
    assert slave.get_real([2, 3]) == [4.0, 0.0]
    assert slave.do_step(0.0, 0.1)
    slave.set_real([1], [300.0])
    assert not slave.do_step(0.1, 0.1)
    logged = [m.msg for m in slave.log_queue]
    assert "setReal: evaluating the outputs: ValueError: b above 100" in logged[-2]
    assert logged[-1].startswith("doStep at t=0.1 s:") and "b above 100" in logged[-1]
