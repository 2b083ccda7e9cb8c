"""FMI 3.0 variants of the MAST FMUs (pythonfmu3): valid, the same numbers as FMI 2.0, run by a C++ host.

The FMI 3.0 slave (fmus/common/fmi3.py) wraps the same blocks with the same behaviour as the FMI 2.0
one: driven with the same inputs the two give the same outputs to the last bit. The ecos command line
runs an FMI 3.0 MAST FMU; libcosim 0.0.6 refuses FMI 3.0. Why the FMI 2.0 FMUs stay the ones to use:
docs/using-the-fmus.md.
"""

from __future__ import annotations

import ctypes
import importlib.util
import zipfile
from pathlib import Path

import numpy as np
import pytest
from lxml import etree

import mast.core.build as build
from mast.core.build import FMUS, block_class, build_all, build_ssp, default_parameters
from mast.core.ssp import read_ssd
from mast.hosts.cosim import HostError, availability, run_host

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("pythonfmu3") is None,
    reason="pythonfmu3 is not installed (pip install -e '.[test]' installs it)",
)

ROOT = Path(__file__).resolve().parents[1]
OK, WARNING, DISCARD, ERROR, FATAL = range(5)
IDENTIFIERS = [
    s.model_identifier
    for s in FMUS
    if s.model_identifier in ("MastActuator", "MastMechanism", "MastController", "MastTrajectory")
]


@pytest.fixture(scope="module", autouse=True)
def _extractions(tmp_path_factory):
    """The FMUs the tests open are extracted into a temporary folder pytest removes (Instance3)."""
    Instance3.folder = tmp_path_factory.mktemp("unzipped")
    yield
    Instance3.folder = None
    Instance3.extracted.clear()


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("build")
    build_all(out, log=lambda *_: None, fmi3=True)
    return out


class Instance3:
    """An FMI 3.0 co-simulation instance through fmpy's FMU3Slave, with its log and raw statuses.

    Instances of one FMU share one extraction (``unzip``, default: the FMU's extraction in ``folder``, set for
    this module's tests to a pytest temporary folder, which pytest removes)."""

    folder: Path | None = None
    extracted: dict[Path, Path] = {}

    def __init__(self, fmu: Path, name: str, unzip: Path | None = None) -> None:
        from fmpy import extract, read_model_description
        from fmpy.fmi3 import FMU3Slave

        self.md = read_model_description(str(fmu))
        if unzip is None and self.folder is not None:
            key = Path(fmu).resolve()
            if key not in self.extracted:
                self.extracted[key] = Path(extract(str(fmu), str(self.folder / str(len(self.extracted)))))
            unzip = self.extracted[key]
        self.unzip = unzip or Path(extract(str(fmu)))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.inputs = [v.name for v in self.md.modelVariables if v.causality == "input"]
        self.outputs = [v.name for v in self.md.modelVariables if v.causality == "output"]
        self.log: list[tuple[int, str]] = []
        self.slave = FMU3Slave(
            guid=self.md.guid,
            unzipDirectory=str(self.unzip),
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )

        def log(_env, status, _category, message):
            self.log.append((status, (message or b"").decode(errors="replace")))

        self.slave.instantiate(loggingOn=True, logMessage=log)

    def start(self, parameters=None, inputs=None) -> None:
        self.slave.enterInitializationMode(startTime=0.0)
        for name, value in {**(parameters or {}), **(inputs or {})}.items():
            self.slave.setFloat64([self.vr[name]], [value])
        self.slave.exitInitializationMode()

    def set(self, **values) -> None:
        self.slave.setFloat64([self.vr[n] for n in values], list(values.values()))

    def get(self, names=None) -> list[float]:
        return self.slave.getFloat64([self.vr[n] for n in (names or self.outputs)])

    def step(self, t: float, h: float) -> int:
        flags = [ctypes.c_bool() for _ in range(3)]
        last = ctypes.c_double()
        return self.slave.dll.fmi3DoStep(
            self.slave.component,
            ctypes.c_double(t),
            ctypes.c_double(h),
            ctypes.c_bool(True),
            *[ctypes.byref(f) for f in flags],
            ctypes.byref(last),
        )

    def close(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()


def test_fmi3_fmus_validate_declare_state_units_time_and_feedthrough_and_fmpy_simulates_them(built):
    """Every FMI 3.0 variant: fmpy validate clean, fmpy's simulate_fmu runs it (inputs at their start
    values), and its ModelStructure declares each output's direct feedthrough as the block does
    (Block.FEEDTHROUGH; none: an empty list), the same as the FMI 2.0 FMU of the model."""
    from fmpy import read_model_description, simulate_fmu
    from fmpy.validation import validate_fmu

    for spec in FMUS:
        identifier = spec.model_identifier
        fmu = built / "fmus3" / f"{identifier}.fmu"
        assert validate_fmu(str(fmu)) == [], identifier
        md = read_model_description(str(fmu))
        assert md.fmiVersion == "3.0" and md.coSimulation.modelIdentifier == identifier
        assert md.coSimulation.canGetAndSetFMUstate and not md.coSimulation.needsExecutionTool
        variables = {v.name: v for v in md.modelVariables}
        assert variables["time"].causality == "independent"
        outputs = [v for v in md.modelVariables if v.causality == "output"]
        assert outputs and all(v.unit for v in outputs)
        assert {u.name for u in md.unitDefinitions} >= {v.unit for v in outputs}
        # the class the FMU wraps: its variables follow its built-in parameters (Block.for_parameters)
        feedthrough = block_class(identifier).for_parameters(default_parameters(identifier)).FEEDTHROUGH
        expected = {v.name: sorted(feedthrough.get(v.name, ())) for v in outputs}
        for md_version in (md, read_model_description(str(built / "fmus" / f"{identifier}.fmu"))):
            declared = {u.variable.name: sorted(d.name for d in u.dependencies) for u in md_version.outputs}
            assert declared == expected, (md_version.fmiVersion, identifier)
        result = simulate_fmu(str(fmu), stop_time=0.005, step_size=1e-3, output_interval=1e-3)
        assert result["time"][-1] == pytest.approx(0.005), identifier
        assert all(np.isfinite(result[v.name]).all() for v in outputs), identifier


@pytest.mark.parametrize("identifier", IDENTIFIERS)
def test_fmi3_variant_computes_what_the_fmi2_fmu_computes(built, identifier, tmp_path):
    from fmpy import extract
    from test_fmi_behaviour import Instance, _input

    fmu2 = built / "fmus" / f"{identifier}.fmu"
    two = Instance(fmu2, "two", Path(extract(str(fmu2), str(tmp_path / "two"))))
    three = Instance3(built / "fmus3" / f"{identifier}.fmu", "three")
    assert two.outputs == three.outputs and two.inputs == three.inputs
    assert two.start() == OK
    three.start()
    h = 1e-3 if identifier == "MastMechanism" else 1e-4
    rows2, rows3 = [], []
    for k in range(200):
        inputs = {name: _input(name, k * h, 0.0) for name in two.inputs}
        for inst in (two, three):
            if inputs:
                inst.set(**inputs)
        assert two.step(k * h, h) == OK and three.step(k * h, h) == OK
        rows2.append(two.get())
        rows3.append(three.get())
    two.close()
    three.close()
    np.testing.assert_array_equal(np.array(rows3), np.array(rows2))
    assert np.ptp(np.array(rows2), axis=0).max() > 0


def test_fmi3_state_rollback_failures_and_bad_parameters(built):
    inst = Instance3(built / "fmus3" / "MastActuator.fmu", "axis")
    inst.start()
    for k in range(20):
        inst.set(i_cmd=2.0, F=6.0)
        assert inst.step(k * 1e-4, 1e-4) == OK
    state = inst.slave.getFMUState()
    ahead = []
    for k in range(20, 60):
        inst.set(i_cmd=3.0, F=6.0)
        assert inst.step(k * 1e-4, 1e-4) == OK
        ahead.append(inst.get())
    inst.slave.setFMUState(state)
    again = []
    for k in range(20, 60):
        inst.set(i_cmd=3.0, F=6.0)
        assert inst.step(k * 1e-4, 1e-4) == OK
        again.append(inst.get())
    np.testing.assert_array_equal(again, ahead)
    inst.slave.freeFMUState(state)
    inst.set(F=float("nan"))
    assert inst.step(60e-4, 1e-4) == DISCARD
    assert inst.log[-1][0] == ERROR and "input 'F' = nan" in inst.log[-1][1]
    inst.close()

    bad = Instance3(built / "fmus3" / "MastActuator.fmu", "bad")
    bad.start({"R": -1.0})
    assert any(s == ERROR and "exitInitializationMode" in m and "'R'" in m for s, m in bad.log)
    assert bad.step(0.0, 1e-4) == DISCARD and "did not initialise" in bad.log[-1][1]
    bad.close()


def test_fmi3_variant_starts_at_the_hosts_start_time(built):
    """pythonfmu3 0.3.4 drops fmi3EnterInitializationMode's start time; the C front hands it to the model
    (fmi3.START_TIME_REFERENCE). Started at t0 = 0.1 s, the trajectory's sine starts there, as in the FMI 2.0
    FMU and in its closed form z_home + amplitude_z sin(2 pi f (t - t0)); it started at 0 before."""
    from fmpy import simulate_fmu

    traj = read_ssd(ROOT / "ssp" / "MAST_standalone.ssd").components["trajectory"].parameters
    runs = [
        simulate_fmu(
            str(built / folder / "MastTrajectory.fmu"),
            start_time=0.1,
            stop_time=0.105,
            step_size=1e-3,
            output_interval=1e-3,
        )
        for folder in ("fmus", "fmus3")
    ]
    expected = traj["z_home"] + traj["amplitude_z"] * np.sin(2 * np.pi * traj["frequency"] * (runs[1]["time"] - 0.1))
    np.testing.assert_allclose(runs[1]["z_cmd"], expected, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(runs[1]["z_cmd"], runs[0]["z_cmd"])
    assert np.ptp(runs[1]["z_cmd"]) > 1e-5


@pytest.fixture(scope="module")
def ssps(built) -> tuple[Path, Path]:
    ssd = ROOT / "ssp" / "MAST_standalone.ssd"
    return (build_ssp(ssd, built / "fmus", built / "ssp2"), build_ssp(ssd, built / "fmus3", built / "ssp3"))


@pytest.mark.skipif(availability("ecos") is not None, reason=f"ecos: {availability('ecos')}")
def test_the_ecos_command_line_runs_an_fmi3_mast_fmu(built):
    """A C++ host through its FMI 3.0 loader. A whole FMI 3.0 system in ecos is not reliable: see the docs."""
    result = run_host(
        "ecos",
        built / "fmus3" / "MastTrajectory.fmu",
        0.5,
        ["instance.z_cmd", "instance.time"],
        sample_step=0.01,
        base_step=0.01,
    )
    traj = read_ssd(ROOT / "ssp" / "MAST_standalone.ssd").components["trajectory"].parameters
    expected = traj["z_home"] + traj["amplitude_z"] * np.sin(2 * np.pi * traj["frequency"] * result.time)
    np.testing.assert_allclose(result["instance.z_cmd"], expected, atol=5.0001e-7)  # 6 printed decimals
    np.testing.assert_allclose(result["instance.time"], result.time, atol=5.0001e-7)
    assert result.time[-1] == pytest.approx(0.5)


@pytest.mark.skipif(availability("libcosim") is not None, reason=f"libcosim: {availability('libcosim')}")
def test_libcosim_0_0_6_cannot_load_fmi3_fmus(ssps):
    """Written down rather than solved: libcosimpy 0.0.6's libcosim handles FMI 1.0 and 2.0 only; it refuses
    an SSP of FMI 3.0 FMUs (docs/using-the-fmus.md). If this starts to fail, update the docs."""
    with pytest.raises(HostError, match="Unsupported FMI version for FMU .*MastMechanism.fmu"):
        run_host("libcosim", ssps[1], 0.01, ["mechanism.z"])


def test_outputs_are_calculated_in_initialization_and_declare_no_start_value(built):
    """The outputs depend on the inputs at the start (the pose on the carriages' positions, rho_cmd on the
    pose command): initial="calculated", no start value, listed as initial unknowns (FMI 2.0 section 2.2.8,
    FMI 3.0 section 2.4.8). 'exact' with start 0 claimed mechanism.z = 0 where it is 0.405 m."""
    from fmpy import read_model_description

    fmi2, fmi3 = sorted((built / "fmus").glob("*.fmu")), sorted((built / "fmus3").glob("*.fmu"))
    assert fmi2 and [f.name for f in fmi2] == [f.name for f in fmi3]  # every FMU in both versions
    fmus = fmi2 + fmi3
    for fmu in fmus:
        md = read_model_description(str(fmu))
        outputs = [v for v in md.modelVariables if v.causality == "output"]
        assert outputs, fmu.name
        for v in outputs:
            assert v.initial == "calculated" and v.start is None, f"{fmu.parent.name}/{fmu.name}: {v.name}"
        assert {u.variable.name for u in md.initialUnknowns} == {v.name for v in outputs}, fmu.name


# -- the FMI state machine, as in FMI 2.0 (test_fmi_behaviour.py) --------------------------------------------
def _values(inst: Instance3, function: str, name_or_vr, value=0.0, ctype=ctypes.c_double) -> int:
    """The raw status of fmi3Set<T> or fmi3Get<T> on one variable (a name, or a bare value reference)."""
    vr = (ctypes.c_uint32 * 1)(inst.vr[name_or_vr] if isinstance(name_or_vr, str) else name_or_vr)
    buf = (ctype * 1)(value)
    return getattr(inst.slave.dll, function)(inst.slave.component, vr, ctypes.c_size_t(1), buf, ctypes.c_size_t(1))


def _enter(inst: Instance3) -> int:
    return inst.slave.dll.fmi3EnterInitializationMode(
        inst.slave.component,
        ctypes.c_bool(False),
        ctypes.c_double(0.0),
        ctypes.c_double(0.0),
        ctypes.c_bool(False),
        ctypes.c_double(0.0),
    )


def _drive(inst: Instance3, first: int, n: int, h: float = 1e-4) -> np.ndarray:
    """Steps first .. first + n - 1 (t = k h) with the inputs of test_fmi_behaviour.drive; the outputs after each."""
    from test_fmi_behaviour import _input

    rows = []
    for k in range(first, first + n):
        inst.set(**{name: _input(name, k * h, 0.0) for name in inst.inputs})
        assert inst.step(k * h, h) == OK, inst.log[-3:]
        rows.append(inst.get())
    return np.array(rows)


CASES = (
    "exit before enter",
    "step before initialization",
    "enter twice",
    "parameter after initialization",
    "output",
    "unknown reference",
    "wrong type",
    "boolean",
    "foreign state",
    "step after terminate",
)


def test_fmi3_illegal_calls_return_error_name_the_fault_and_change_nothing(built):
    """The FMI 3.0 variants behind the C front (fmus/common/pythonfmu_shim.c, FMI_VERSION 3): a call the
    state does not allow, a set the variable does not allow, an unknown value reference, another FMU's
    state: fmi3Error with one message (status Error) naming the fault, no Fatal, and the instance runs on
    as one that never saw the call."""
    fmu = built / "fmus3" / "MastActuator.fmu"
    trajectory = Instance3(built / "fmus3" / "MastTrajectory.fmu", "trajectory")
    trajectory.start()
    foreign = trajectory.slave.getFMUState()
    for case in CASES:
        inst, fresh = Instance3(fmu, "axis"), Instance3(fmu, "fresh")

        def refused(status: int, *words: str) -> None:
            assert status == ERROR, (case, inst.log[-2:])
            assert inst.log[-1][0] == ERROR and all(w in inst.log[-1][1] for w in words), (case, inst.log[-2:])
            assert not [m for s, m in inst.log if s == FATAL], case  # pythonfmu3's own Fatal report is not passed on

        if case == "exit before enter":
            refused(
                inst.slave.dll.fmi3ExitInitializationMode(inst.slave.component),
                "exitInitializationMode",
                "not allowed in instantiated",
            )
        elif case == "step before initialization":
            refused(inst.step(0.0, 1e-4), "doStep", "not allowed in instantiated")
        elif case == "enter twice":
            assert _enter(inst) == OK
            refused(_enter(inst), "enterInitializationMode", "not allowed in initialization mode")
        if case == "enter twice":
            inst.set(tau_c=0.0718)
            assert inst.slave.dll.fmi3ExitInitializationMode(inst.slave.component) == OK
        else:
            inst.start({"tau_c": 0.0718})
        fresh.start({"tau_c": 0.0718})
        np.testing.assert_array_equal(_drive(inst, 0, 3), _drive(fresh, 0, 3))
        first = 3
        if case == "parameter after initialization":  # was: Fatal, and every later call refused
            refused(
                _values(inst, "fmi3SetFloat64", "tau_c", 0.05),
                "setFloat64",
                "parameter 'tau_c' is fixed",
                "before exitInitializationMode",
                "step mode",
            )
            assert inst.get(["tau_c"]) == [0.0718]
        elif case == "output":
            refused(_values(inst, "fmi3SetFloat64", "tau_m", 1.0), "'tau_m' is output", "only inputs and parameters")
        elif case == "unknown reference":
            refused(_values(inst, "fmi3GetFloat64", 4711), "getFloat64", "value reference 4711 is not a variable of")
        elif case == "wrong type":
            refused(
                _values(inst, "fmi3SetInt32", "tau_c", 1, ctypes.c_int32),
                "setInt32",
                "'tau_c'",
                "is of type Float64, not Int32",
            )
        elif case == "boolean":
            refused(_values(inst, "fmi3GetBoolean", "rho", False, ctypes.c_bool), "getBoolean", "not Boolean")
        elif case == "foreign state":
            refused(inst.slave.dll.fmi3SetFMUState(inst.slave.component, foreign), "not an FMU state of MastActuator")
        elif case == "step after terminate":
            assert inst.slave.dll.fmi3Terminate(inst.slave.component) == OK
            refused(inst.step(3e-4, 1e-4), "doStep", "not allowed in terminated")
            assert _values(inst, "fmi3GetFloat64", "rho") == OK  # a legal call after it
            fresh.slave.terminate()
            for i in (inst, fresh):  # and a reset, to run again
                assert i.slave.dll.fmi3Reset(i.slave.component) == OK
                i.start({"tau_c": 0.0718})
            first = 0
        np.testing.assert_array_equal(_drive(inst, first, 10), _drive(fresh, first, 10))
        for i in (inst, fresh):
            i.close()
    trajectory.slave.freeFMUState(foreign)
    trajectory.close()


def test_fmi3_without_the_c_front_an_illegal_call_is_fatal_and_the_instance_refuses_what_follows(built, tmp_path):
    """An FMI 3.0 variant with pythonfmu3's own binary (a build without a C compiler) cannot say fmi3Error: it
    says fmi3Fatal, the message says Fatal too, and every later call is refused, as FMI requires after Fatal."""
    from fmpy import extract

    unzip = Path(extract(str(built / "fmus3" / "MastActuator.fmu"), str(tmp_path / "fmu")))
    folder = unzip / "binaries" / "x86_64-linux"
    (folder / "MastActuator.pythonfmu.so").replace(folder / "MastActuator.so")
    inst = Instance3(built / "fmus3" / "MastActuator.fmu", "plain", unzip)
    inst.start()
    assert inst.step(0.0, 1e-4) == OK
    assert _values(inst, "fmi3SetFloat64", "R", 1.0) == FATAL
    assert any(s == FATAL and "parameter 'R' is fixed" in m for s, m in inst.log), inst.log[-3:]
    assert inst.step(1e-4, 1e-4) == FATAL and any("failed earlier" in m for s, m in inst.log[-2:])
    inst.slave.freeInstance()


# -- direct feedthrough ------------------------------------------------------------------------------------
HALVER_SCRIPT = """
from pythonfmu3 import Fmi3Slave

from fmus.common.fmi3 import BlockSlave3
from test_fmi_behaviour import Halver


class HalverFmu(BlockSlave3, Fmi3Slave):
    '''y = k b at the communication point, z advances with the steps.'''

    block_class = Halver
"""


def test_fmi3_feedthrough_output_follows_its_input_and_is_declared_in_the_model_structure(tmp_path):
    """Block.FEEDTHROUGH through the FMI 3.0 wrapper and the C front, on a block of its own (test_fmi_behaviour's
    Halver: y = k b, z only in doStep): ModelStructure declares y's dependency on b (value reference, kind
    'dependent') and none for z; fmpy validates the FMU; after fmi3SetFloat64 of b in step mode y is k b
    without a doStep, while z waits for the step; a failed evaluation is logged and refuses the next step."""
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu
    from pythonfmu3.builder import FmuBuilder as Fmu3Builder

    script = tmp_path / "halver_fmi3.py"
    script.write_text(HALVER_SCRIPT)
    fmu = Path(Fmu3Builder.build_FMU(script, dest=tmp_path, needsExecutionTool=False, canGetAndSetFMUState=True))
    build._rewrite(fmu, lambda items: build._put_front(items, "HalverFmu", 3))
    assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    with zipfile.ZipFile(fmu) as z:
        structure = etree.fromstring(z.read("modelDescription.xml")).find("ModelStructure")
    assert {
        o.get("valueReference"): (o.get("dependencies"), o.get("dependenciesKind"))
        for o in structure.iterfind("Output")
    } == {str(vr["y"]): (str(vr["b"]), "dependent"), str(vr["z"]): ("", None)}
    inst = Instance3(fmu, "halver")
    inst.start({"k": 0.5})
    inst.set(a=3.0, b=8.0)
    assert inst.get(["y", "z"]) == [4.0, 0.0]  # y follows b at once; z has not stepped
    assert inst.step(0.0, 0.1) == OK and inst.get(["y", "z"]) == [4.0, 0.1]
    inst.set(b=-2.0)
    assert inst.get(["y"]) == [-1.0]
    inst.set(b=300.0)
    assert inst.log[-1] == (
        ERROR,
        "setFloat64: evaluating the outputs: ValueError: b above 100 (the '%' in this "
        "message reaches an FMI 3.0 host as it is)",
    ), inst.log[-2:]  # not a format
    assert inst.step(0.1, 0.1) == DISCARD and "b above 100" in inst.log[-1][1]
    inst.set(b=10.0)
    assert inst.step(0.1, 0.1) == OK and inst.get(["y", "z"]) == [5.0, pytest.approx(0.2)]
    inst.close()


def test_feedthrough_outputs_of_the_mast_fmi3_fmus_follow_their_inputs_as_the_model_does(built):
    """Every MAST model that declares direct feedthrough (Block.FEEDTHROUGH), as an FMI 3.0 variant: after
    fmi3SetFloat64 of its inputs in step mode, with no doStep, its feedthrough outputs are what the Python
    model computes (Block.evaluate) from the same inputs and state, at the start and after steps."""
    from test_fmi_behaviour import _input

    checked = []
    for spec in FMUS:
        identifier, defaults = spec.model_identifier, build.default_parameters(spec.model_identifier)
        cls = block_class(identifier).for_parameters(defaults)  # the FMU's class (its built-in parameters')
        if not cls.FEEDTHROUGH:
            continue
        inst = Instance3(built / "fmus3" / f"{identifier}.fmu", "feedthrough")
        block = cls(defaults, name="direct")
        inputs = {name: _input(name, 0.0, 0.0) for name in cls.INPUTS}
        inst.start(inputs=inputs)
        block.set(**inputs)
        block.initialize(0.0)
        names, h = list(cls.FEEDTHROUGH), 1e-4
        for k in range(3):
            inputs = {name: _input(name, (k + 0.5) * h, 0.3) for name in cls.INPUTS}  # not the last ones
            inst.set(**inputs)
            block.set(**inputs)
            block.evaluate()
            assert inst.get(names) == [block.get(name) for name in names], (identifier, k)
            assert inst.step(k * h, h) == OK, inst.log[-2:]
            block.do_step(k * h, h)
        inst.close()
        checked.append(identifier)
    if not checked:
        pytest.skip("no MAST model declares direct feedthrough here (the wrapper's feedthrough: the Halver tests)")
