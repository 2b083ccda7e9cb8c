"""Native FMUs (mast build --native): compiled C generated from the models, no Python at run time.

Against the Python FMUs of the same models: the same modelDescription, the same trajectories
(every native SSP variant, the default run and a 10 Hz sine), the same error messages for bad
parameters and failing steps. FMI behaviour through the C API (several instances, get/set FMU
state, calls out of order) and 200 instantiate/free cycles of a C host under valgrind.
The FMUs are compiled once for the module (-O2).
"""

from __future__ import annotations

import ctypes
import math
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from lxml import etree
from test_fmi_behaviour import DISCARD, ERROR, OK, Instance, _input, drive

from mast.core.build import FMUS, build_fmu, build_ssp
from mast.core.motion import SineMotion
from mast.core.native.build import SUPPORT, build_native_all
from mast.core.native.compiler import compiler, fmi_headers
from mast.core.native.translate import TranslationError, to_c
from mast.core.run import simulate

ROOT = Path(__file__).resolve().parents[1]
NATIVE = (
    "MastActuator",
    "MastMechanism",
    "MastController",
    "MastTrajectory",
    "Mast3PRS120",
    "Mast3PRSInclined",
    "MastActuatorsOnly",
    "MastFeedForwardController",
    "MastComputedTorqueController",
    "MastWorkspaceController",
)
MECHANISMS = ("MastMechanism", "Mast3PRS120", "Mast3PRSInclined", "MastActuatorsOnly")
SYSTEMS = (
    "MAST",
    "MAST_standalone",
    "MAST_3PRS_120",
    "MAST_3PRS_inclined",
    "MAST_actuators_only",
    "MAST_feedforward",
    "MAST_computed_torque",
    "MAST_workspace",
)
#: native and Python FMUs run the same floating-point operations (mast.core.native.translate): the issue asks 1e-9
TOLERANCE = 1e-9


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("native")
    for spec in FMUS:
        if spec.model_identifier in NATIVE:
            build_fmu(spec, out / "fmus")
    ssds = [ROOT / "ssp" / f"{name}.ssd" for name in SYSTEMS]
    for ssd in ssds:
        build_ssp(ssd, out / "fmus", out / "ssp")
    build_native_all(out, ssds, log=lambda *_: None, fmus=NATIVE)
    return out


def _relative_error(a, b) -> float:
    """The largest difference of a signal relative to its largest value, or to 1e-6 of its SI unit for a
    signal that stays below (a pose coordinate the symmetric motion keeps at zero but for rounding, 1e-16 rad
    or 1e-30 m, whose rounding differs: the native actuator's exact discretisation comes from another expm
    than scipy's, docs/native.md)."""
    worst = 0.0
    for name in a.signals:
        x, y = np.asarray(a.signals[name]), np.asarray(b.signals[name])
        assert x.shape == y.shape, name
        scale = max(float(np.abs(x).max()), 1e-6)
        worst = max(worst, float(np.abs(x - y).max()) / scale)
    return worst


# -- what a native FMU is --------------------------------------------------------------------------
def test_native_fmus_declare_the_python_fmus_variables_validate_and_carry_sources_not_python(built):
    from fmpy.validation import validate_fmu

    from mast.core.build import block_class
    from mast.core.native.build import SUPPORT_FILES
    from mast.core.native.models import runtime_files

    for ident in NATIVE:
        native, python = built / "fmus" / "native" / f"{ident}.fmu", built / "fmus" / f"{ident}.fmu"
        assert validate_fmu(str(native)) == [], ident
        with zipfile.ZipFile(native) as zn, zipfile.ZipFile(python) as zp:
            mn, mp = (
                etree.fromstring(zn.read("modelDescription.xml")),
                etree.fromstring(zp.read("modelDescription.xml")),
            )
            names = zn.namelist()
            binary = zn.read(f"binaries/linux64/{ident}.so")
        variables = [(etree.tostring(v), v.get("valueReference")) for v in mn.iter("ScalarVariable")]
        assert variables == [(etree.tostring(v), v.get("valueReference")) for v in mp.iter("ScalarVariable")], ident
        assert etree.tostring(mn.find("UnitDefinitions")) == etree.tostring(mp.find("UnitDefinitions"))
        assert {k: v for k, v in mn.find("CoSimulation").attrib.items()} == dict(mp.find("CoSimulation").attrib)
        assert mn.get("guid") != mp.get("guid") and "native" in mn.get("generationTool")
        sources = [f.get("name") for f in mn.find("CoSimulation/SourceFiles")]
        runtime = (*SUPPORT_FILES, *runtime_files(block_class(ident)))  # the same for every model of a kind
        assert sorted(sources) == sorted([*(n for n in runtime if n.endswith(".c")), f"{ident}_model.c"])
        headers = {f"sources/{n}" for n in runtime if n.endswith(".h")}
        assert {f"sources/{s}" for s in sources} | headers | {"sources/mast_model.h", "sources/mast_native.h"} <= set(
            names
        )
        assert ("sources/config.h" in names) == (ident != "MastTrajectory")  # the sizes (and a controller's layout)
        assert b"libpython" not in binary and b"Py_Initialize" not in binary and b"numpy" not in binary


def test_the_sources_in_the_archive_compile_into_a_working_binary(built, tmp_path):
    """A host on another platform compiles sources/ with its FMI headers: here, the same check with gcc."""
    with zipfile.ZipFile(built / "fmus" / "native" / "MastTrajectory.fmu") as z:
        z.extractall(tmp_path)
    library = tmp_path / "rebuilt.so"
    c_files = sorted(str(p) for p in (tmp_path / "sources").glob("*.c"))
    subprocess.run(
        [compiler(), "-O2", "-shared", "-fPIC", f"-I{fmi_headers()}", "-o", str(library), *c_files, "-lm"],
        check=True,
        capture_output=True,
    )
    shutil.copy(library, tmp_path / "binaries" / "linux64" / "MastTrajectory.so")
    from fmpy import simulate_fmu

    result = simulate_fmu(str(tmp_path), stop_time=0.25, output_interval=0.25, fmi_type="CoSimulation")
    z_home, amplitude = 0.4051470164434615, 0.01  # ssp/resources/home_3prs.ssv, trajectory_z.ssv
    assert result["z_cmd"][-1] == pytest.approx(z_home + amplitude * math.sin(2 * math.pi * 0.25), rel=1e-12)


# -- the same trajectories -------------------------------------------------------------------------
@pytest.mark.parametrize("system", SYSTEMS)
def test_every_native_system_reproduces_the_python_fmus(built, system):
    stimulus = None if system == "MAST_standalone" else SineMotion("z", 0.01, 1.0)
    python = simulate(built / "ssp" / f"{system}.ssp", stimulus, 0.2)
    native = simulate(built / "ssp" / "native" / f"{system}.ssp", stimulus, 0.2)
    # the same floats: the actuator's exact discretisation too (fixed_order.expm is mast_expm's arithmetic, issue 24;
    # before, scipy's expm made this 6.8e-10)
    assert _relative_error(python, native) == 0.0


def test_a_10_hz_sine_reproduces_the_python_fmus_also_with_the_tunable_trajectory(built):
    stimulus = SineMotion("z", 0.002, 10.0)
    python = simulate(built / "ssp" / "MAST.ssp", stimulus, 0.3)
    native = simulate(built / "ssp" / "native" / "MAST.ssp", stimulus, 0.3)
    assert _relative_error(python, native) <= TOLERANCE
    z = np.asarray(native.signals["z_cmd"] if "z_cmd" in native.signals else next(iter(native.signals.values())))
    assert np.ptp(z) > 0.003  # the sine is there
    ten_hz = {"trajectory": {"frequency": 10.0, "amplitude_z": 0.002}}  # a parameter set at run time
    python = simulate(built / "ssp" / "MAST_standalone.ssp", None, 0.3, parameters=ten_hz)
    native = simulate(built / "ssp" / "native" / "MAST_standalone.ssp", None, 0.3, parameters=ten_hz)
    assert _relative_error(python, native) <= TOLERANCE


# -- FMI behaviour -----------------------------------------------------------------------------------
def _native(built: Path, ident: str, name: str) -> Instance:
    return Instance(built / "fmus" / "native" / f"{ident}.fmu", name)


def test_instances_are_independent_and_a_restored_state_reproduces_the_continuation(built):
    alone = _native(built, "MastActuator", "alone")
    assert alone.start() == OK
    expected = drive(alone, 0, 60, seed=1.0)
    a, b = _native(built, "MastActuator", "a"), _native(built, "MastActuator", "b")
    assert a.start() == OK and b.start() == OK
    rows = []
    for k in range(60):  # interleaved, different inputs
        drive(b, k, 1, seed=2.0)
        rows.append(drive(a, k, 1, seed=1.0)[0])
    assert np.array_equal(np.array(rows), expected)
    state = a.slave.getFMUstate()
    first = drive(a, 60, 40, seed=1.0)
    a.slave.setFMUstate(state)
    assert np.array_equal(drive(a, 60, 40, seed=1.0), first)
    a.slave.freeFMUstate(state)
    for inst in (alone, a, b):
        inst.close()


@pytest.mark.parametrize("ident", ["MastController", "MastFeedForwardController"])
def test_the_controllers_commands_change_in_do_step_only(built, ident):
    """No direct feedthrough (docs/interfaces.md, Timing), Python and native FMUs alike: the commands read right
    after setting the inputs are those read before (the last step's); setting them again at the same point,
    first wrong and then right and one by one, gives what one set gives (the last value counts, at doStep);
    a step with no input set runs the laws on the held inputs."""
    runs = []
    for fmu in (built / "fmus" / f"{ident}.fmu", built / "fmus" / "native" / f"{ident}.fmu"):
        rows = {}
        for how in ("once", "again", "held"):
            inst = Instance(fmu, "controller")
            assert inst.start() == OK
            out = []
            for k in range(30):
                t = k * 1e-3
                real = {name: _input(name, t, 1.0) for name in inst.inputs}
                before = inst.get()
                if how == "again":
                    inst.set(**{name: v + 0.01 for name, v in real.items()})
                    for name, v in real.items():
                        inst.set(**{name: v})
                elif how == "once" or k % 2 == 0:
                    inst.set(**real)
                out.append(inst.get())  # the commands at t, before the step
                assert out[-1] == before
                assert inst.step(t, 1e-3) == OK, inst.log[-2:]
            rows[how] = np.array(out)
            inst.close()
        assert np.array_equal(rows["again"], rows["once"])
        assert np.abs(rows["once"][1:] - rows["once"][:-1]).max() > 0.0
        # held: at the odd points the step's laws run on the held inputs, so the commands after it differ from
        # the once run
        assert not np.array_equal(rows["held"], rows["once"])
        runs.append(rows["once"])
    assert np.abs(runs[0] - runs[1]).max() <= TOLERANCE * np.abs(runs[0]).max()


def test_calls_out_of_order_return_error_with_a_logged_message_and_the_instance_survives(built):
    inst = _native(built, "MastActuator", "axis")
    assert inst.step(0.0, 1e-4) == ERROR
    assert "doStep before exitInitializationMode" in inst.log[-1][1]
    vr = ctypes.c_uint * 1
    value = (ctypes.c_double * 1)(0.0)
    assert inst.dll.fmi2GetReal(inst.c, vr(99999), 1, value) == ERROR
    assert "unknown value reference 99999" in inst.log[-1][1]
    assert inst.dll.fmi2SetReal(inst.c, vr(inst.vr["rho"]), 1, value) == ERROR  # an output
    assert "'rho' is an output" in inst.log[-1][1]
    assert inst.dll.fmi2SetReal(inst.c, vr(inst.vr["n_dof"]), 1, value) == ERROR  # an Integer variable
    assert inst.start() == OK
    value[0] = 0.5
    assert inst.dll.fmi2SetReal(inst.c, vr(inst.vr["R"]), 1, value) == ERROR  # fixed parameter after init
    assert "parameter 'R' is fixed" in inst.log[-1][1]
    assert inst.dll.fmi2EnterInitializationMode(inst.c) == ERROR
    assert inst.step(0.0, 1e-4) == OK  # nothing changed: it still steps
    inst.close()


@pytest.mark.parametrize(
    "ident, parameter, value",
    [
        ("MastMechanism", "m_platform", -1.0),
        ("MastActuator", "R", 0.0),
        ("MastController", "k_v", -2.5),
        ("MastFeedForwardController", "M_load", -1.0),
        ("MastComputedTorqueController", "k_T", -0.3),
    ],
)
def test_bad_parameters_get_the_python_fmus_message(built, ident, parameter, value):
    messages = []
    for fmu in (built / "fmus" / f"{ident}.fmu", built / "fmus" / "native" / f"{ident}.fmu"):
        inst = Instance(fmu, "component")
        assert inst.start({parameter: value}) == OK  # as the Python FMUs: refused steps follow
        messages.append(next(m for s, m in inst.log if s == ERROR and "exitInitializationMode" in m))
        assert inst.step(0.0, 1e-3) == DISCARD and "did not initialise" in inst.log[-1][1]
        inst.close()
    assert messages[0] == messages[1]
    assert parameter in messages[1] and "expected a float in" in messages[1]


def test_a_failing_step_is_refused_with_the_python_fmus_message(built):
    messages = []
    for fmu in (built / "fmus" / "MastActuator.fmu", built / "fmus" / "native" / "MastActuator.fmu"):
        inst = Instance(fmu, "axis2")
        assert inst.start() == OK and inst.step(0.0, 1e-4) == OK
        inst.set(F=float("inf"))
        assert inst.step(1e-4, 1e-4) == DISCARD
        assert inst.slave.getBooleanStatus(3)  # fmi2Terminated: the FMU asks the host to stop
        messages.append(inst.log[-1][1])
        inst.close()
    assert messages[0] == messages[1]


def test_a_pose_within_the_singularity_margin_is_refused_by_both_routes_with_the_same_message(built):
    """Engine.dk's margin (engine.MARGIN) in C too: on the inclined design's path from home towards its
    parallel singularity (tests/test_workspace.py), 98 % of the way is within the margin, 97 % is not."""
    from test_designs import Own

    from fmus.mechanism.engine import MARGIN
    from mast.analyses import workspace as W

    machine = W.machine("3PRS_inclined")
    engine, own = machine.engine(), Own({**machine.params, "g": 9.81})
    home = np.array(engine.dk(machine.rho_home)[0])
    singular = np.array((0.252056, math.radians(17.30), math.radians(-17.45)))
    outside, inside = (home + s * (singular - home) for s in (0.97, 0.98))
    assert engine.margins(outside).parallel > MARGIN > engine.margins(inside).parallel > 0.5 * MARGIN
    messages = []
    for fmu in (built / "fmus" / "Mast3PRSInclined.fmu", built / "fmus" / "native" / "Mast3PRSInclined.fmu"):
        for q, accepted in ((outside, True), (inside, False)):
            inst = Instance(fmu, "table")
            rho = own.rho(q)
            inst.set(rho_1=rho[0], rho_2=rho[1], rho_3=rho[2])
            inst.start()
            errors = [m for s, m in inst.log if s == ERROR]
            if accepted:
                assert not errors and inst.step(0.0, 1e-3) == OK, errors
            else:
                assert errors and "SingularityError" in errors[-1] and "within the margin of a parallel (" in errors[-1]
                messages.append(errors[-1])
            inst.close()
    assert messages[0] == messages[1]


@pytest.mark.parametrize(
    "ident, h, tuned",
    [
        # the gains: computed at initialisation by the controller's own cascade_gains, transmission_ratio
        ("MastController", 1e-4, {"k_v": 41.5, "k_p": 0.031, "k_i": 2.7, "i_max": 3.5, "p": 0.006, "i_r": 2.5}),
        # and the other controllers' own gains: feedforward_gains, error_gains, pose_gains
        ("MastFeedForwardController", 1e-4, {"k_v": 41.5, "k_i": 2.7, "k_ff_v": 0.6, "k_ff_tau": 0.8}),
        ("MastComputedTorqueController", 1e-4, {"i_max": 0.5, "omega_n": 90.0, "zeta": 0.8}),
        (
            "MastWorkspaceController",
            1e-4,
            {
                "k_v": 41.5,
                "k_v_scale_z": 1.2,
                "k_v_scale_psi": 0.7,
                "k_v_scale_theta": 1.5,
                "k_p": 0.031,
                "k_i": 2.7,
                "i_max": 3.5,
            },
        ),
        # the masses, inertias and g: inputs of the engine's traced functions (designs.traced_engine)
        (
            "MastMechanism",
            1e-3,
            {"m_leg": 0.45, "I_leg": 0.003, "m_platform": 3.1, "I_px": 0.011, "I_py": 0.013, "I_pz": 0.02, "g": 9.7},
        ),
        # the controllers' cycle times (their schedule) and kinematic model (the engine traced with the geometry
        # as inputs), and the feed-forward and computed-torque controllers' inverse model's bodies
        ("MastController", 1e-3, {"T_pos": 2e-3, "T_vel": 5e-4, "H": 0.41, "r": 0.34, "alpha_2": 1.6, "p": 0.006}),
        ("MastWorkspaceController", 1e-3, {"T_vel": 4e-4, "L": 0.27, "beta": 0.05, "i_r": 2.5}),
        (
            "MastFeedForwardController",
            1e-3,
            {"T_pos": 2e-3, "H": 0.41, "m_platform": 2.5, "m_payload": 3.0, "payload_z": 0.05},
        ),
        ("MastComputedTorqueController", 1e-3, {"T_vel": 5e-4, "r": 0.34, "g": 9.7, "I_py": 0.02}),
        # and their inverse model's actuator constants (inverse_model.model_constants at initialisation)
        (
            "MastFeedForwardController",
            1e-3,
            {
                "M_load": 3.1,
                "J1_scale": 1.3,
                "J_motor": 2e-5,
                "tau_c": 0.05,
                "omega_c": 0.7,
                "b_v": 3e-4,
                "tau_s": 0.02,
                "omega_s": 4.0,
                "k_T": 0.3,
                "g_guide": 5.0,
                "i_r": 2.5,
            },
        ),
        (
            "MastComputedTorqueController",
            1e-3,
            {
                "M_load": 3.1,
                "J1_scale": 1.3,
                "J_guide": 2e-6,
                "tau_c": 0.05,
                "b_v": 3e-4,
                "k_T": 0.3,
                "g_guide": 5.0,
                "p": 0.006,
            },
        ),
    ],
)
def test_parameters_read_at_run_time_are_tunable_in_any_host(built, ident, h, tuned):
    """Set by the host as on the Python FMU (docs/native.md, Parameters): the same outputs, step for step."""
    rows = []
    for fmu in (built / "fmus" / f"{ident}.fmu", built / "fmus" / "native" / f"{ident}.fmu"):
        inst = Instance(fmu, "component")
        assert _start(inst, tuned) == OK and not [m for s, m in inst.log if s == ERROR], inst.log[-3:]
        rows.append(drive(inst, 0, 40, h=h, seed=3.0))
        inst.close()
    default = _native(built, ident, "component")
    assert default.start() == OK
    untuned = drive(default, 0, 40, h=h, seed=3.0)
    default.close()
    assert np.abs(rows[0] - untuned).max() > 1e-3 * np.abs(untuned).max()  # the parameters matter
    assert np.abs(rows[0] - rows[1]).max() <= TOLERANCE * np.abs(rows[0]).max()  # measured: 0


def _start(inst: Instance, parameters: dict) -> int:
    """Instance.start with each parameter set by its type (Real, Integer, String)."""
    inst.slave.setupExperiment(startTime=0.0)
    inst.slave.enterInitializationMode()
    for name, value in parameters.items():
        setter = {str: inst.slave.setString, int: inst.slave.setInteger}.get(type(value), inst.slave.setReal)
        setter([inst.vr[name]], [value])
    return inst.dll.fmi2ExitInitializationMode(inst.c)


def _carriages(inst: Instance, n: int, h: float) -> np.ndarray:
    """n steps of a mechanism with each carriage on its own sine (the platform tilts); the outputs after each."""
    rows = []
    for k in range(n):
        t = k * h
        values = {}
        for i in range(3):
            w = 2 * math.pi * (2.0 + i)
            values |= {
                f"rho_{i + 1}": 0.15 + 0.012 * math.sin(w * t + i),
                f"rho_dot_{i + 1}": 0.012 * w * math.cos(w * t + i),
                f"rho_ddot_{i + 1}": -0.012 * w * w * math.sin(w * t + i),
            }
        inst.set(**values)
        assert inst.step(t, h) == OK, inst.log[-3:]
        rows.append(inst.get())
    return np.array(rows)


@pytest.mark.parametrize(
    "ident, tuned",
    [
        # geometry, bodies, payload and g of the T design: one generated code for every parameter set
        (
            "MastMechanism",
            {
                "H": 0.41,
                "r": 0.33,
                "L": 0.27,
                "alpha_2": 1.62,
                "m_leg": 0.45,
                "I_px": 0.011,
                "g": 9.7,
                "m_payload": 4.0,
                "payload_x": 0.02,
                "payload_z": 0.08,
                "I_payload_xx": 0.02,
                "I_payload_yy": 0.03,
                "I_payload_zz": 0.04,
                "I_payload_xy": 0.002,
            },
        ),
        # the inclined design made vertical (Python traces other formulas then; C computes the same floats)
        ("Mast3PRSInclined", {"beta": 0.0, "H": 0.4}),
        # actuators alone, attached again: the inverse dynamics instead of the kinematics only
        ("MastActuatorsOnly", {"attached": 1, "beta": 0.1, "H": 0.45}),
    ],
)
def test_every_mechanism_parameter_is_tunable_in_any_host(built, ident, tuned):
    """Geometry, payload and bodies set through start values as on the Python FMU: the same outputs (0 measured)."""
    rows = []
    for fmu in (built / "fmus" / f"{ident}.fmu", built / "fmus" / "native" / f"{ident}.fmu"):
        inst = Instance(fmu, "table")
        assert _start(inst, tuned) == OK and not [m for s, m in inst.log if s == ERROR], inst.log[-3:]
        rows.append(_carriages(inst, 40, 5e-3))
        inst.close()
    default = _native(built, ident, "table")
    assert default.start() == OK
    untuned = _carriages(default, 40, 5e-3)
    default.close()
    assert np.abs(rows[0] - untuned).max() > 1e-3 * np.abs(untuned).max()  # the parameters matter
    assert np.abs(rows[0] - rows[1]).max() <= TOLERANCE * np.abs(rows[0]).max()  # measured: 0


@pytest.mark.parametrize(
    "ident, tuned, words",
    [
        ("MastMechanism", {"r": 0.45}, "parameter 'r' = 0.45: must be < H = 0.4 m"),
        ("MastMechanism", {"L": 0.04}, "parameter 'L' = 0.04: must exceed H - r"),
        ("MastMechanism", {"kinematics": "9XYZ"}, "parameter 'kinematics' = '9XYZ': expected one of"),
        (
            "MastMechanism",
            {"m_payload": 1.0, "I_payload_xx": 0.01, "I_payload_xy": 0.5},
            "inertia tensor is not positive semi-definite",
        ),
        ("Mast3PRSInclined", {"H": 0.9}, "cannot be assembled at the level pose with the sliders at the foot"),
        ("MastController", {"T_pos": 1.05e-3}, "parameter 'T_pos' = 0.00105 s must be an integer multiple of T_cur"),
        ("MastWorkspaceController", {"r": 0.5}, "parameter 'r' = 0.5: must be < H"),
    ],
)
def test_a_mechanism_or_controller_that_cannot_be_built_is_refused_with_the_python_fmus_message(
    built, ident, tuned, words
):
    messages = []
    for fmu in (built / "fmus" / f"{ident}.fmu", built / "fmus" / "native" / f"{ident}.fmu"):
        inst = Instance(fmu, "table")
        _start(inst, tuned)
        messages.append(next(m for s, m in inst.log if s == ERROR and "exitInitializationMode" in m))
        inst.close()
    assert words in messages[1] and "ParameterError" in messages[1]
    # the same words, up to the failed admissibility check's, which C gives without its values (docs/native.md)
    assert messages[0].split(" guides: ")[0] == messages[1].split(" guides: ")[0]


@pytest.mark.parametrize("ident", ["MastWorkspaceController", "MastComputedTorqueController"])
def test_a_controller_whose_direct_kinematics_fails_is_refused_with_the_python_fmus_message(built, ident):
    """Measured joints no pose has: the workspace law's and the inverse model's direct kinematics fail,
    named as in Python (the traced check's own words differ: C has no values in them, docs/native.md)."""
    from test_fmi_behaviour import _input

    messages = []
    for fmu in (built / "fmus" / f"{ident}.fmu", built / "fmus" / "native" / f"{ident}.fmu"):
        inst = Instance(fmu, "controller")
        assert inst.start() == OK
        inst.set(**{**{n: _input(n, 0.0, 0.0) for n in inst.inputs}, "rho_1": 0.02, "rho_2": 0.6, "rho_3": 0.02})
        assert inst.step(0.0, 1e-4) == DISCARD
        messages.append(inst.log[-1][1])
        inst.close()
    assert "KinematicsError" in messages[1] and "exceeds the admissible tilt" in messages[1]
    assert messages[0].split(", where:")[0] == messages[1].split(", where:")[0]


def test_200_instantiate_free_cycles_of_a_c_host_are_clean_under_valgrind_and_5000_keep_memory_flat(built, tmp_path):
    valgrind = shutil.which("valgrind")
    host = tmp_path / "cycles"
    subprocess.run(
        [
            compiler(),
            "-O2",
            f"-I{fmi_headers()}",
            "-o",
            str(host),
            str(ROOT / "benchmarks" / "native_cycles.c"),
            "-ldl",
        ],
        check=True,
        capture_output=True,
    )
    for ident, h in (("MastActuator", 1e-4), ("MastMechanism", 1e-3), ("MastController", 1e-4)):
        folder = tmp_path / ident
        with zipfile.ZipFile(built / "fmus" / "native" / f"{ident}.fmu") as z:
            z.extractall(folder)
        guid = etree.parse(str(folder / "modelDescription.xml")).getroot().get("guid")
        args = [str(host), str(folder / "binaries" / "linux64" / f"{ident}.so"), guid, "200", repr(h)]
        plain = subprocess.run([*args[:3], "5000", args[4]], capture_output=True, text=True, timeout=60)
        assert plain.returncode == 0, plain.stderr
        rss10, rss5000, ok, logged = map(int, plain.stdout.split())
        # KiB, page-granular: measured 0-68 (a one-off, not growing with the cycles); a leak of 30 bytes
        # per cycle would show 146, an instance (over 1 KiB) 5000
        assert ok == 1 and logged >= 15000 and rss5000 - rss10 <= 128, plain.stdout
        if valgrind:
            checked = subprocess.run(
                [valgrind, "-q", "--error-exitcode=3", "--leak-check=full", "--errors-for-leak-kinds=definite", *args],
                capture_output=True,
                text=True,
                timeout=300,
            )
            assert checked.returncode == 0, checked.stderr[-3000:]


def test_the_c_backend_refuses_python_outside_the_generated_subset():
    with pytest.raises(TranslationError, match="line 2"):
        to_c("def f(x):\n    return [x]\n", "f")
    with pytest.raises(TranslationError, match="loop"):
        to_c("def f(x):\n    for i in x:\n        pass\n", "f", arrays=("x",))


# -- hosts with no Python ----------------------------------------------------------------------------
def test_ecos_command_line_runs_the_native_ssp_without_python_and_libcosim_runs_it_too(built):
    from mast.core.run import default_signals
    from mast.core.ssp import SSPArchive
    from mast.hosts.cosim import ABSOLUTE, PRINTED, availability, comparable, deviations, out_of_agreement, run_host

    ssp = built / "ssp" / "native" / "MAST_standalone.ssp"
    with SSPArchive(ssp) as archive:
        signals = comparable(default_signals(archive.system))  # every output of every component but RATES
    reference = simulate(ssp, None, 0.3, record=signals)
    for host, kwargs in (("ecos", {"python_free": True}), ("libcosim", {})):
        if availability(host):
            pytest.skip(f"{host}: {availability(host)}")
        result = run_host(host, ssp, 0.3, signals, **kwargs)
        assert "exit_signal" not in result.stats, (host, result.stats["exit_signal"])
        dev = deviations(result, reference, signals)
        over = out_of_agreement(dev, reference, PRINTED if host == "ecos" else ABSOLUTE)  # ecos prints 6 decimals
        assert not over, f"{host} differs from our master: { {s: dev[s] for s in over} }"
        assert np.ptp(result["mechanism.z"]) > 0.005  # the 10 mm sine ran


#: the feed-forward and computed-torque controllers' inverse model: another actuator than the plant's
_INVERSE_MODEL = {"M_load": 3.1, "J1_scale": 1.3, "tau_c": 0.05, "b_v": 3e-4, "k_T": 0.3, "g_guide": 5.0}


@pytest.mark.parametrize(
    "system, changed, stop",
    [
        (
            "MAST",
            {
                "actuator_2": {"R": 0.35, "tau_c": 0.03},
                "mechanism": {"m_platform": 2.5, "L": 0.265, "m_payload": 2.0, "payload_z": 0.05},
                "controller": {"k_v": 40.0, "L": 0.265, "T_pos": 2e-3},
            },
            0.2,
        ),
        ("MAST_feedforward", {"controller": _INVERSE_MODEL}, 0.05),
        ("MAST_computed_torque", {"controller": _INVERSE_MODEL}, 0.05),
    ],
)
def test_our_master_runs_a_native_system_with_another_parameter_set_like_the_python_fmus(
    built, tmp_path, monkeypatch, system, changed, stop
):
    """Parameters changed by the caller: the native FMUs read them at run time, as the Python FMUs; only a
    parameter a native FMU holds as generated makes the master generate the model for it (mast.core.native.build)."""
    monkeypatch.setenv("MAST_NATIVE_CACHE", str(tmp_path))
    stimulus = SineMotion("z", 0.01, 2.0)
    python = simulate(built / "ssp" / f"{system}.ssp", stimulus, stop, parameters=changed)
    native = simulate(built / "ssp" / "native" / f"{system}.ssp", stimulus, stop, parameters=changed)
    assert _relative_error(python, native) <= TOLERANCE
    # every parameter changed here is read at run time: nothing is generated for them
    assert not list(tmp_path.glob("*/*.fmu"))
    unchanged = simulate(built / "ssp" / f"{system}.ssp", stimulus, stop)
    assert _relative_error(python, unchanged) > 1e-3  # the change matters


def test_the_c_backend_computes_what_the_python_computes_branch_for_branch(tmp_path):
    """An independent check of mast.core.native.translate: Python subset -> C -> ctypes, on a grid of inputs."""
    source = (
        "def f(a, b):\n"
        "    s = 0.0\n"
        "    for _ in range(5):\n"
        "        if a < b < 2.0: s += a*b - 0.1\n"
        "        elif not a > 1.0 or b == 0.5: s -= b/3.0\n"
        "        else:\n"
        "            s = s*0.5 + tanh(a)\n"
        "            break\n"
        "        a, b = b, a - 0.25\n"
        "    return (s, a, b, a % 2.0 if a > 0.0 else -1.0)\n"
    )
    namespace = {"tanh": math.tanh}
    exec(source, namespace)  # noqa: S102 (the test's own source)
    (tmp_path / "f.c").write_text(
        '#include "mast_native.h"\n'
        + to_c(source, "f", static=False)
        + "double m(double x, double y) { return mast_mod(x, y); }\n"
    )
    subprocess.run(
        [
            compiler(),
            "-O2",
            "-ffp-contract=off",
            "-shared",
            "-fPIC",
            f"-I{SUPPORT}",
            "-o",
            str(tmp_path / "f.so"),
            str(tmp_path / "f.c"),
            "-lm",
        ],
        check=True,
        capture_output=True,
    )
    f = ctypes.CDLL(str(tmp_path / "f.so")).f
    f.argtypes = [ctypes.c_double, ctypes.c_double, ctypes.POINTER(ctypes.c_double)]
    out = (ctypes.c_double * 4)()
    grid = [-1.3, 0.0, 0.5, 0.7, 1.0, 1.9, 2.0, 3.25]
    for a in grid:
        for b in grid:
            assert f(a, b, out) == 0
            assert list(out) == list(namespace["f"](a, b)), (a, b)
    # % of the tick counters: integer remainder where exact, fmod elsewhere; always Python's (x >= 0) bit for bit
    m = ctypes.CDLL(str(tmp_path / "f.so")).m
    m.restype, m.argtypes = ctypes.c_double, [ctypes.c_double, ctypes.c_double]
    for x in (0.0, 1.0, 9.0, 10.0, 12345.0, 2.0**31 - 1, 2.0**31, 2.0**40 + 7, 0.5, 7.25, 1e300):
        for y in (1.0, 3.0, 10.0, 2.0**31 + 1, 0.3, 2.5):
            assert math.copysign(1.0, m(x, y)) == 1.0 and m(x, y) == x % y, (x, y)
    # a slice store that reads the array it writes (a shift register): every value before any store
    (tmp_path / "g.c").write_text(
        to_c("def g(x):\n    x[1:] = (x[0], x[1], x[2] + 1.0)\n    return 0\n", "g", arrays=("x",), static=False)
    )
    subprocess.run(
        [compiler(), "-O2", "-shared", "-fPIC", "-o", str(tmp_path / "g.so"), str(tmp_path / "g.c")],
        check=True,
        capture_output=True,
    )
    x = (ctypes.c_double * 4)(1.0, 2.0, 3.0, 4.0)
    assert ctypes.CDLL(str(tmp_path / "g.so")).g(x) == 0 and list(x) == [1.0, 1.0, 2.0, 4.0]
    # the controllers' tick (fmus/controller/tick.py), which Python runs too: a call returning a tuple, stores by
    # index and into a bounded slice, with Python's meaning (the list keeps its length)
    pair = "def pair(u, v):\n    return (u*v, u - v)\n"
    tick = "def tick(x):\n    a, b = pair(x[0], x[1])\n    x[0] = b\n    x[2:4] = (a, x[0] + a)\n    return 0\n"
    (tmp_path / "t.c").write_text(to_c(pair, "pair") + to_c(tick, "tick", arrays=("x",), calls=("pair",), static=False))
    subprocess.run(
        [
            compiler(),
            "-O2",
            "-ffp-contract=off",
            "-shared",
            "-fPIC",
            "-o",
            str(tmp_path / "t.so"),
            str(tmp_path / "t.c"),
        ],
        check=True,
        capture_output=True,
    )
    exec(pair + tick, namespace)  # noqa: S102 (the test's own source)
    x, y = (ctypes.c_double * 5)(0.3, 1.7, 0.0, 0.0, 9.0), [0.3, 1.7, 0.0, 0.0, 9.0]
    assert ctypes.CDLL(str(tmp_path / "t.so")).tick(x) == 0 and namespace["tick"](y) == 0
    assert list(x) == y and y[4] == 9.0 and y[0] == 0.3 - 1.7
    with pytest.raises(TranslationError, match="length"):
        to_c("def f(x):\n    x[1:2] = (1.0, 2.0)\n    return 0\n", "f", arrays=("x",))


def test_what_the_parameters_alone_fix_is_computed_once_and_the_floats_do_not_change():
    """translate.split_invariants on the mechanism's traced functions (the native mechanism computes their
    parameter-only part at initialisation): run as Python, invariants then main give the floats of the whole
    function, bit for bit, at poses and parameter sets that differ; only parameter-only assignments move."""
    import random

    from fmus.mechanism.designs import TRACED_PARAMETERS, traced_engine
    from mast.core.build import default_parameters
    from mast.core.native.translate import split_invariants

    params = default_parameters("Mast3PRSInclined")
    eng = traced_engine(params, "Mast3PRSInclined")
    rng = random.Random(5)
    for name, n_q in (("ikjac", 3), ("forces", 18), ("pose", 3)):
        fn = eng._fn(name)
        invariants, main, n = split_invariants(fn.source, TRACED_PARAMETERS)
        ns = dict(fn.namespace)
        exec(invariants + "\n" + main, ns)  # noqa: S102 (generated by the function under test)
        hoisted = invariants.splitlines()[1:-1]
        assert n > 0 and all(f"q{k}" not in line and "_check" not in line for line in hoisted for k in range(3))
        assert any("_cos(alpha_1)" in line for line in hoisted) and "_cos(q1)" in main  # trig of the geometry
        for _ in range(20):
            P = [v * rng.uniform(0.97, 1.03) for v in eng._pv]  # another parameter set each time
            q = [0.4 + rng.uniform(-0.01, 0.01), rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05)]
            args = q + [rng.uniform(-1.0, 1.0) for _ in range(n_q - 3)]
            K = ns[f"{name}_invariants"](*P)
            assert len(K) == n and ns[name](*args, *P, list(K)) == fn(*args, *P)  # the same floats (==)


def test_only_the_models_a_generator_knows_claim_a_native_form():
    """The EMPS bench's load axis lives beside the MAST actuator (fmus/actuator/) but is another model:
    its FMU must be skipped by `mast build --native`, not generated as the MAST actuator."""
    from mast.core.native.build import has_native_form

    claimed = {spec.model_identifier for spec in FMUS if has_native_form(spec.model_identifier)}
    assert {"MastActuator", "MastMechanism", "MastController", "MastTrajectory"} <= claimed
    assert not claimed & {"MastLoadAxis", "MastEmpsController"}


# -- the actuator: every parameter read at run time, its discretisation computed in the FMU ------------
@pytest.mark.parametrize(
    "h, tuned",
    [
        # and the drive's current loop (current_gains, at initialisation), over steps of ten ticks
        (1e-3, {"R": 0.35, "tau_c": 0.03, "K_t": 900.0, "k_pc": 0.3, "k_ic": 1000.0, "u_max": 20.0}),
        # Stribeck, ripple and the torque measurement, at a current-loop cycle no system uses
        (
            2.5e-4,
            {
                "tau_s": 0.02,
                "omega_s": 5.0,
                "tau_ripple": 0.01,
                "T_meas": 3e-4,
                "delay_meas": 2.5e-4,
                "tau_offset": 0.01,
                "T_cur": 2.5e-4,
            },
        ),
        (1e-4, {"backlash": 0.002, "J1_scale": 0.8}),
    ],
)
def test_the_native_actuator_reads_its_parameters_at_run_time_as_the_python_fmu(built, h, tuned):
    """The same trajectory as the Python FMU with the same settings: the exact discretisation (expm of the
    parameters' matrices, docs/native.md) computed in C; the Python FMU's comes from scipy (measured: at
    most 3e-11 relative, in rho_ddot, over 150 current-loop ticks)."""
    rows = []
    cycle = {k: v for k, v in tuned.items() if k == "T_cur"}
    steps = 150 // round(h / cycle.get("T_cur", 1e-4))
    for fmu in (built / "fmus" / "MastActuator.fmu", built / "fmus" / "native" / "MastActuator.fmu"):
        inst = Instance(fmu, "axis")
        assert inst.start(tuned) == OK and not [m for s, m in inst.log if s == ERROR]
        rows.append(drive(inst, 0, steps, h=h, seed=3.0))
        inst.close()
    default = _native(built, "MastActuator", "axis")
    assert default.start(cycle) == OK
    untuned = drive(default, 0, steps, h=h, seed=3.0)
    default.close()
    scale = np.abs(rows[0]).max(axis=0)
    assert (np.abs(rows[0] - untuned).max(axis=0) > 1e-3 * scale).any()  # the parameters matter
    assert (np.abs(rows[0] - rows[1]).max(axis=0) <= TOLERANCE * scale).all()


def test_the_native_actuator_follows_a_host_that_varies_its_step_and_refuses_a_step_off_the_tick(built):
    """More step sizes than DISCRETISATIONS_KEPT, back and forth (multiples of T_cur: the axis behind the
    current loop steps T_cur), and between them steps that are not whole multiples of T_cur: refused
    (fmi2Discard) with the same message naming h and T_cur, the state untouched (the run goes on equal)."""
    from mast.core.native.models import DISCRETISATIONS_KEPT

    sizes = [1e-4 * (1 + k) for k in range(DISCRETISATIONS_KEPT + 3)]
    order = [sizes[(3 * k) % len(sizes) if k % 22 < 11 else k % len(sizes)] for k in range(44)]
    off_tick = {5: 1.5e-4, 17: 5e-5, 30: 3.3e-4}
    rows, refused = [], []
    for fmu in (built / "fmus" / "MastActuator.fmu", built / "fmus" / "native" / "MastActuator.fmu"):
        inst = Instance(fmu, "axis")
        assert inst.start({"tau_s": 0.02}) == OK
        t, out, messages = 0.0, [], []
        for k, h in enumerate(order):
            inst.set(i_cmd=4.0 * math.sin(40.0 * t), F=6.0)
            if k in off_tick:
                assert inst.step(t, off_tick[k]) == DISCARD
                messages.append(inst.log[-1][1])
            assert inst.step(t, h) == OK, inst.log[-2:]
            out.append(inst.get())
            t += h
        rows.append(np.array(out))
        refused.append(messages)
        inst.close()
    assert len(set(order)) > DISCRETISATIONS_KEPT
    assert refused[0] == refused[1]
    for message, h in zip(refused[0], off_tick.values()):
        assert f"step size h = {h!r} s is not a positive integer multiple of T_cur = 0.0001 s" in message
    scale = np.abs(rows[0]).max(axis=0)
    assert (np.abs(rows[0] - rows[1]).max(axis=0) <= TOLERANCE * scale).all()


def test_the_native_axis_keeps_and_evicts_its_discretisations_as_the_python_model_steps(built, tmp_path, monkeypatch):
    """The cache of DISCRETISATIONS_KEPT step sizes (the slot of the last h, the oldest recomputed when it
    comes back) is unreachable through MastActuator: its axis steps T_cur whatever the host's step. So the
    voltage-in axis alone (ActuatorBlock, which the generator also emits) is compiled here and stepped with
    DISCRETISATIONS_KEPT + 3 sizes, most of them not multiples of 100 us, all of them first and then again
    in another order (slots evicted and recomputed), against ActuatorBlock in Python (measured: 7.4e-12); the
    torque measurement's delay line laid out again for every new size (TorqueSensor's relayout); then the chain
    n_dof = 3 of the same binary, set at run time (generated with N_MAX = 3: a third of the compile)."""
    from fmpy.fmi2 import FMU2Slave

    from fmus.actuator.model import ActuatorBlock
    from mast.core.build import default_parameters
    from mast.core.native import models
    from mast.core.native.build import native_sources
    from mast.core.native.compiler import compile_shared
    from mast.core.native.models import DISCRETISATIONS_KEPT

    monkeypatch.setattr(models, "N_MAX", 3)
    # the drive's modelDescription made the axis': u in for i_cmd, no u out, no loop parameters
    root = etree.fromstring(zipfile.ZipFile(built / "fmus" / "MastActuator.fmu").read("modelDescription.xml"))
    order = [*ActuatorBlock.INPUTS, *ActuatorBlock.OUTPUTS, *(p.name for p in ActuatorBlock.PARAMETERS)]
    variables = root.find("ModelVariables")
    for sv in list(variables):
        if sv.get("name") == "i_cmd":
            sv.set("name", "u")
        elif sv.get("name") == "u" or sv.get("name") not in order:
            variables.remove(sv)
    assert [sv.get("name") for sv in variables] == order
    for vr, sv in enumerate(variables):
        sv.set("valueReference", str(vr))
    measured = {"T_meas": 2e-4, "delay_meas": 3.3e-4, "tau_offset": 0.01}
    params = {k: v for k, v in {**default_parameters("MastActuator"), "tau_s": 0.02, **measured}.items() if k in order}
    sources, xml = native_sources("MastActuator", ActuatorBlock, params, etree.tostring(root))
    library = tmp_path / "binaries" / "linux64" / "MastActuator.so"
    library.parent.mkdir(parents=True)
    compile_shared(sources, library)
    sizes = [1e-4, 2.5e-5, 7e-5, 1.3e-4, 3e-4, 5e-5, 1e-3, 4.1e-4, 2e-4, 6.7e-5, 9e-4][: DISCRETISATIONS_KEPT + 3]
    assert len(set(sizes)) == DISCRETISATIONS_KEPT + 3
    outputs = [order.index(name) for name in ActuatorBlock.OUTPUTS]
    # and the chain n_dof = 3 in the same binary, set at run time (a few steps of each size)
    for tuned, steps in (
        ({"tau_s": 0.02, **measured}, 4 * len(sizes) + 20),
        ({"tau_s": 0.02, **measured, "n_dof": 3, **_chain_lists(3)}, 30),
    ):
        native = FMU2Slave(
            guid=etree.fromstring(xml).get("guid"),
            unzipDirectory=str(tmp_path),
            modelIdentifier="MastActuator",
            instanceName="axis",
        )
        native.instantiate()
        native.setupExperiment(startTime=0.0)
        native.enterInitializationMode()
        for name, value in tuned.items():
            setter = {int: native.setInteger, str: native.setString, float: native.setReal}[type(value)]
            setter([order.index(name)], [value])
        native.exitInitializationMode()
        python = ActuatorBlock({**params, **tuned}, "axis")
        python.set(u=0.0, F=6.0)
        python.initialize(0.0)
        t, rows = 0.0, []
        for k in range(steps):  # each size twice in a row: the last slot's reuse too
            h = sizes[3 * (k // 2) % len(sizes) if k < 2 * len(sizes) else k // 2 % len(sizes)]
            u = 3.0 * math.sin(40.0 * t)
            native.setReal([0, 1], [u, 6.0])
            native.doStep(t, h)
            python.set(u=u, F=6.0)
            python.do_step(t, h)
            rows.append((native.getReal(outputs), [python.get(name) for name in ActuatorBlock.OUTPUTS]))
            t += h
        native.terminate()
        native.freeInstance()
        got, expected = np.array(rows).transpose(1, 0, 2)
        scale = np.abs(expected).max(axis=0)
        assert (np.abs(got - expected).max(axis=0) <= TOLERANCE * scale).all(), tuned


def test_the_native_drive_holds_its_voltage_limit_without_winding_up_as_the_python_fmu(built):
    """u_max = 1 V, a 6 A command out of reach for 40 ticks then 0 A (test_drive.py checks the Python model
    against a hand-written loop): u saturates, never exceeds u_max, and leaves the limit at the first tick
    with the new command (measured: an unclamped integrator holds it there 55 of the remaining 60 ticks);
    native = Python FMU."""
    rows = []
    for fmu in (built / "fmus" / "MastActuator.fmu", built / "fmus" / "native" / "MastActuator.fmu"):
        inst = Instance(fmu, "axis")
        assert inst.start({"u_max": 1.0}) == OK
        out = []
        for k in range(100):
            inst.set(i_cmd=6.0 if k < 40 else 0.0, F=0.0)
            assert inst.step(k * 1e-4, 1e-4) == OK, inst.log[-2:]
            out.append(inst.get())
        u = np.array(out)[:, inst.outputs.index("u")]
        assert np.abs(u).max() == 1.0 and (u[:40] == 1.0).sum() >= 38
        assert (u[40:] < 1.0).all()
        rows.append(np.array(out))
        inst.close()
    scale = np.abs(rows[0]).max(axis=0)
    assert (np.abs(rows[0] - rows[1]).max(axis=0) <= TOLERANCE * scale).all()


def test_the_native_actuator_refuses_a_bad_parameter_set_with_the_python_fmus_message(built):
    messages = []
    for fmu in (built / "fmus" / "MastActuator.fmu", built / "fmus" / "native" / "MastActuator.fmu"):
        inst = Instance(fmu, "axis")
        assert inst.start({"rho_0": 0.9}) == OK
        messages.append(next(m for s, m in inst.log if s == ERROR and "exitInitializationMode" in m))
        assert inst.step(0.0, 1e-4) == DISCARD
        inst.close()
    assert (
        messages[0] == messages[1] and "parameter 'rho_0' = 0.9: expected a position inside the stroke" in messages[0]
    )


def test_the_c_matrix_exponential_agrees_with_scipy_over_the_parameter_ranges(tmp_path):
    """mast_expm (mast_linalg.c) against scipy.linalg.expm, the independent route: the actuator's augmented
    matrices [[A B], [0 0]] h for parameter sets spread over decades around the paper's, and steps from
    10 us to 10 ms (the substep rule keeps omega_max h_sub <= 2; here up to 40 unsubdivided)."""
    from scipy.linalg import expm, matrix_balance

    from fmus.actuator.model import ActuatorBlock
    from mast.core.build import default_parameters

    source = tmp_path / "expm.c"
    source.write_text(
        '#include "mast_native.h"\nint expm_c(int n, const double *M, double *E) { return mast_expm(n, M, E); }\n'
    )
    library = tmp_path / "expm.so"
    subprocess.run(
        [
            compiler(),
            "-O2",
            "-ffp-contract=off",
            "-shared",
            "-fPIC",
            f"-I{SUPPORT}",
            "-o",
            str(library),
            str(source),
            str(SUPPORT / "mast_linalg.c"),
            "-lm",
        ],
        check=True,
        capture_output=True,
    )
    expm_c = ctypes.CDLL(str(library)).expm_c
    rng = np.random.default_rng(7)
    own = {p.name for p in ActuatorBlock.PARAMETERS}  # the axis behind the drive's current loop
    base = {k: v for k, v in default_parameters("MastActuator").items() if k in own}
    worst = 0.0
    for k in range(60):
        factors = {
            name: 10.0 ** rng.uniform(-1.0, 1.0)
            for name in ("R", "L", "k_T", "k_E", "J_motor", "J_guide", "M_load", "K_t", "C_t", "b_v")
        }
        params = {**base, **{name: base[name] * f for name, f in factors.items()}, "n_dof": 1 + k % 2}
        block = ActuatorBlock(params)
        n = block.A.shape[0]
        M = np.zeros((n + 2, n + 2))
        M[:n, :n], M[:n, n:] = block.A, block.B
        omega = max(block._omega_max, 1.0)
        for h in (1e-5, 1e-4, 1e-3, 1e-2):
            h = min(h, 40.0 / omega)
            X = np.ascontiguousarray(M * h)
            E = np.zeros_like(X)
            assert (
                expm_c(
                    n + 2,
                    X.ctypes.data_as(ctypes.POINTER(ctypes.c_double)),
                    E.ctypes.data_as(ctypes.POINTER(ctypes.c_double)),
                )
                == 0
            )
            reference = expm(X)
            # normwise, each state on its own scale (the matrix mixes A, rad and rad/s): in the coordinates
            # LAPACK's balancing chooses, D^-1 E D
            d = matrix_balance(X, permute=False, separate=True)[1][0]
            scaled = d[None, :] / d[:, None]
            worst = max(
                worst,
                float(
                    np.abs((E - reference) * scaled).sum(axis=0).max() / np.abs(reference * scaled).sum(axis=0).max()
                ),
            )
    assert worst < 1e-11, worst  # measured: 3.4e-13


def test_the_native_actuator_refuses_what_it_cannot_compute_with_a_message(built):
    """Parameters beyond floating point (R / L = inf) and a measurement delay longer than its delay line
    (models.SENSOR_SAMPLES steps): a refused step with a message, never a hang or a crash."""
    messages = []
    for fmu in (built / "fmus" / "MastActuator.fmu", built / "fmus" / "native" / "MastActuator.fmu"):
        inst = Instance(fmu, "axis")
        assert inst.start({"L": 1e-310}) == OK
        assert inst.step(0.0, 1e-4) == DISCARD
        messages.append(inst.log[-1][1])
        inst.close()
    assert messages[0] == messages[1] and "no substep gives a monotone friction update" in messages[0]
    inst = _native(built, "MastActuator", "axis")
    assert inst.start({"delay_meas": 1.0}) == OK and inst.step(0.0, 1e-4) == DISCARD
    assert "parameter 'delay_meas' = 1.0 s is 10000 steps of h = 0.0001 s" in inst.log[-1][1]
    inst.close()


def _chain_lists(n: int) -> dict:
    """A chain of n_dof = n >= 3 (the two-inertia model's guide side split in n - 1 bodies and springs)."""
    return {
        "J_chain": " ".join(["1.2e-4"] + [repr(2.1e-4 / (n - 1))] * (n - 1)),
        "K_chain": " ".join([repr(1500.0 * (n - 1))] * (n - 1)),
        "C_chain": " ".join(["0.01"] * (n - 1)),
    }


def _start_with(inst: Instance, parameters: dict) -> int:
    """setupExperiment, enterInitializationMode, the parameters by type (Integer, String, Real),
    exitInitializationMode."""
    inst.slave.setupExperiment(startTime=0.0)
    inst.slave.enterInitializationMode()
    for name, value in parameters.items():
        setter = {int: inst.slave.setInteger, str: inst.slave.setString, float: inst.slave.setReal}[type(value)]
        setter([inst.vr[name]], [value])
    return inst.dll.fmi2ExitInitializationMode(inst.c)


def test_one_native_actuator_runs_every_n_dof_up_to_n_max_set_at_run_time_as_the_python_fmu(built):
    """n_dof is read at run time (docs/native.md): the one native MastActuator set to 1, 2, 3 and N_MAX before
    initialisation, with other parameters on top, against the Python FMU with the same settings (measured: at
    most 1.4e-11 relative, at n_dof = N_MAX: the expm, docs/native.md); bad chain lists get the Python FMU's messages;
    N_MAX + 1 is refused with a message
    naming it, N_MAX and what to do."""
    from mast.core.native.models import N_MAX

    python, native = built / "fmus" / "MastActuator.fmu", built / "fmus" / "native" / "MastActuator.fmu"
    cases = [
        ({"n_dof": 1, "R": 0.35, "tau_s": 0.02, "T_meas": 2e-4}, None),
        ({"n_dof": 2, "backlash": 0.002}, None),
        (
            {
                "n_dof": 3,
                "J_chain": "1e-4, 4e-5 2e-4",
                "K_chain": "700 2000",
                "C_chain": "0.01 0.02",
                "R": 0.35,
                "tau_s": 0.02,
                "T_meas": 2e-4,
            },
            None,
        ),
        ({"n_dof": N_MAX, **_chain_lists(N_MAX), "tau_ripple": 0.01}, None),
        (
            {"n_dof": 3, **_chain_lists(3), "K_chain": "900"},
            "expected 2 space separated numbers > 0 for n_dof = 3, got 1",
        ),
        ({"n_dof": 4, **_chain_lists(4), "C_chain": "0.01 -1 0"}, "item '-1' is not a finite number >= 0"),
        (
            {"n_dof": 1, "backlash": 0.002},
            "backlash is modelled in the two-inertia transmission only (n_dof = 2, here 1)",
        ),
    ]
    runs = []
    for parameters, expected in cases:
        rows, messages = [], []
        for fmu in (python, native):
            inst = Instance(fmu, "axis")
            assert _start_with(inst, parameters) == OK
            messages += [m for s, m in inst.log if s == ERROR]
            if expected is None:
                rows.append(drive(inst, 0, 30, h=1e-3, seed=3.0))
            inst.close()
        if expected is None:
            assert not messages
            scale = np.abs(rows[0]).max(axis=0)
            assert (np.abs(rows[0] - rows[1]).max(axis=0) <= TOLERANCE * scale).all(), parameters
            runs.append(rows[0])
        else:
            assert len(messages) == 2 and messages[0] == messages[1] and expected in messages[0], messages
    for a, b in zip(runs, runs[1:]):  # each n_dof another model
        assert np.abs(a - b).max() > 1e-6 * np.abs(a).max()
    inst = _native(built, "MastActuator", "axis")
    assert _start_with(inst, {"n_dof": N_MAX + 1, **_chain_lists(N_MAX + 1)}) == OK
    message = next(m for s, m in inst.log if s == ERROR)
    assert (
        f"parameter 'n_dof' = {N_MAX + 1}: this native FMU has the chains n_dof = 1..{N_MAX} (N_MAX = {N_MAX})"
        in message
        and "mast build --native" in message
    )
    assert inst.step(0.0, 1e-3) == DISCARD
    inst.close()


def test_our_master_generates_the_native_actuator_for_an_n_dof_above_its_chains(built, tmp_path, monkeypatch):
    """The route for n_dof > N_MAX (mast.core.native.build.for_parameters), made cheap with N_MAX = 1: the
    fixture's FMU (chains 1..N_MAX) runs n_dof = 3 itself; with N_MAX = 1 an FMU generated for n_dof = 2 (chains
    1, 2) does not, and the master generates one with the chain 3, which runs as the Python FMU."""
    from mast.core.build import default_parameters
    from mast.core.native import models
    from mast.core.native.build import build_native_fmu, for_parameters, generated_for

    monkeypatch.setenv("MAST_NATIVE_CACHE", str(tmp_path / "cache"))
    wanted = {"n_dof": 3, **_chain_lists(3)}
    native = built / "fmus" / "native" / "MastActuator.fmu"
    assert for_parameters(native, wanted) == native and not (tmp_path / "cache").exists()
    monkeypatch.setattr(models, "N_MAX", 1)
    small = build_native_fmu(
        "MastActuator", built / "fmus" / "MastActuator.fmu", tmp_path / "small", default_parameters("MastActuator")
    )  # chains 1 and 2 (its own n_dof)
    assert for_parameters(small, {"n_dof": 2}) == small
    made = for_parameters(small, wanted)
    assert made.parent.parent == tmp_path / "cache" and generated_for(made)["parameters"]["n_dof"] == 3
    assert for_parameters(small, wanted) == made  # kept
    rows = []
    for fmu in (built / "fmus" / "MastActuator.fmu", made):
        inst = Instance(fmu, "axis")
        assert _start_with(inst, {**wanted, "tau_c": 0.03}) == OK and not [m for s, m in inst.log if s == ERROR]
        rows.append(drive(inst, 0, 30, h=1e-3, seed=3.0))
        inst.close()
    assert (np.abs(rows[0] - rows[1]).max(axis=0) <= TOLERANCE * np.abs(rows[0]).max(axis=0)).all()


class _Climb:
    """The home pose, then 20 mm higher every 10 ms (no ``extremes``: no workspace check), until a carriage
    leaves its stroke (0.152 m: at 0.033 s)."""

    reads = ("mechanism.z", "mechanism.psi", "mechanism.theta")

    def start(self, t0, read):
        self.home = [read(s) for s in self.reads]

    def __call__(self, t):
        return [self.home[0] + 0.02 * int(t / 0.01), self.home[1], self.home[2]]


@pytest.mark.parametrize("route", ["native", "python"])
def test_the_compiled_exchange_loop_is_the_python_loop_call_for_call(built, route, monkeypatch):
    """mast.core.exchange against the master's Python loop on the same FMUs: the same floats (a 10 Hz sine,
    recorded every base step; native: also every third), and (native) a run that fails stops with the same message and
    keeps the same
    partial results."""
    from mast.core.exchange import library
    from mast.core.master import SimulationError

    assert library() is not None, "no compiled exchange loop (no C compiler?)"
    ssp = built / "ssp" / ("native" if route == "native" else "") / "MAST.ssp"
    stop = 0.2 if route == "native" else 0.05
    runs = {}
    for loop in ("1", "0"):  # MAST_PYTHON_EXCHANGE: 1 the Python loop, 0 the compiled one
        monkeypatch.setenv("MAST_PYTHON_EXCHANGE", loop)
        every_tick = simulate(ssp, SineMotion("z", 0.002, 10.0), stop, record_step=None)
        failed = None
        if route == "native":  # and a record step that does not divide the run: 2000 ticks, every third
            thirds = simulate(ssp, SineMotion("z", 0.002, 10.0), stop, record_step=3e-4)
            every_tick.signals.update({f"{name} (every 0.3 ms)": v for name, v in thirds.signals.items()})
            with pytest.raises(SimulationError) as failed:  # a carriage leaves its stroke
                simulate(ssp, _Climb(), 0.2, parameters={f"actuator_{k}": {"rho_max": 0.152} for k in (1, 2, 3)})
        runs[loop] = every_tick, failed
    (python, p_fail), (compiled, c_fail) = runs["1"], runs["0"]
    assert len(python.time) == round(stop / 1e-4) + 1 and list(python.signals) == list(compiled.signals)
    for name in python.signals:
        np.testing.assert_array_equal(compiled[name], python[name], err_msg=name)
    if route == "native":
        p_fail, c_fail = p_fail.value, c_fail.value
        assert "carriage left the stroke" in str(p_fail) and str(c_fail) == str(p_fail)
        assert len(c_fail.result.time) == len(p_fail.result.time) == 34
        for name in p_fail.result.signals:
            np.testing.assert_array_equal(c_fail.result[name], p_fail.result[name], err_msg=name)
