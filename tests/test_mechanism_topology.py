"""The layers around the engine follow the mechanism's topology (issue 25): a scratch mechanism with two
drives and the coordinates (z, theta) drives the mechanism block (and its FMU's variables), the trajectory
block, the motion stimulus and the admissibility check; a motion axis the system lacks is refused by name."""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from fmus.common import tracer as E
from fmus.mechanism import designs
from fmus.mechanism.engine import Body, Description, Evaluation
from fmus.mechanism.kinematics import KinematicsError
from fmus.mechanism.model import MechanismBlock, Variables
from fmus.mechanism.topology import Coordinate, Drive, Topology
from fmus.trajectory.model import TrajectoryBlock
from mast.core.admissible import CommandError, check_commands, trajectory_extremes
from mast.core.motion import PoseStep, SineMotion, bind, system_axes


def _reach(w2) -> None:
    if not w2 > 0.0:
        raise KinematicsError("pose unreachable: a leg is too short")


class Planar2(Description):
    """Two vertical guides at x = +-H in the x-z plane; slider i carries a rigid leg of length L to the point
    (+-r, 0, 0) of a platform that heaves (z) and pitches (theta about y), guided in x, y, psi and phi.
    Constructed from the 3PRS's geometry parameters H, r, L and its platform's mass and inertia."""

    name = "2PRR"
    coordinates = ("z", "theta")
    joints = ("rho_1", "rho_2")

    def __init__(self, H, r, L, m_platform=0.0, I_p=(0.0, 0.0, 0.0)):
        self.H, self.r, self.L = float(H), float(r), float(L)
        Ix, Iy, Iz = (float(v) for v in I_p)
        self.bodies = (
            Body("platform", float(m_platform), (0.0, 0.0, 0.0), ((Ix, 0.0, 0.0), (0.0, Iy, 0.0), (0.0, 0.0, Iz))),
        )
        self.lengths = (1.0, self.r)

    def key(self):
        return ("Planar2", self.H, self.r, self.L, self.bodies)

    def evaluate(self, q):
        z, theta = q
        c, s = E.cos(theta), E.sin(theta)
        rho = []
        for side in (1.0, -1.0):  # the platform point R (side r, 0, 0) with R = Ry(theta)
            u = side * self.H - side * self.r * c
            w2 = self.L * self.L - u * u
            E.require(_reach, w2)
            rho.append((z - side * self.r * s) - E.sqrt(w2))
        R = ((c, 0.0, s), (0.0, 1.0, 0.0), (-s, 0.0, c))
        return Evaluation(rho, (0.0, 0.0, z, 0.0, theta, 0.0), [((0.0, 0.0, z), R)])

    def guess(self, rho):
        gap = self.H - self.r
        return (0.5 * (rho[0] + rho[1]) + math.sqrt(self.L * self.L - gap * gap), 0.0)

    @property
    def topology(self):
        stroke = (0.0, 0.3)
        return Topology(
            self.name,
            (Coordinate("z"), Coordinate("theta")),
            (Drive("rho_1", "linear", stroke), Drive("rho_2", "linear", stroke)),
            self.guess((0.15, 0.15)),
        )


@pytest.fixture
def planar(monkeypatch, mechanism_params):
    """The parameters of the scratch mechanism (``kinematics`` = 2PRR, registered for this test)."""

    def build(params, masses=True):
        return Planar2(
            params["H"],
            params["r"],
            params["L"],
            m_platform=params["m_platform"] if masses else 0.0,
            I_p=(params["I_px"], params["I_py"], params["I_pz"]) if masses else (0.0, 0.0, 0.0),
        )

    monkeypatch.setitem(designs.KINEMATICS, "2PRR", build)
    return {**mechanism_params, "kinematics": "2PRR"}


def test_variables_follow_the_drives_and_coordinates():
    full = Variables.of(("psi", "theta", "phi"), ("rotary", "rotary", "linear"))
    io = full.required()  # the joint motion in, F and the pose out: what a mechanism must have to plug in
    assert io.inputs == (
        "rho_1",
        "rho_2",
        "rho_3",
        "rho_dot_1",
        "rho_dot_2",
        "rho_dot_3",
        "rho_ddot_1",
        "rho_ddot_2",
        "rho_ddot_3",
    )
    assert io.outputs == ("F_1", "F_2", "F_3", "x", "y", "z", "psi", "theta", "phi")
    assert [io.units[v] for v in ("rho_1", "rho_dot_1", "rho_ddot_1", "F_1")] == ["rad", "rad/s", "rad/s2", "N.m"]
    assert [io.units[v] for v in ("rho_3", "rho_dot_3", "rho_ddot_3", "F_3")] == ["m", "m/s", "m/s2", "N"]
    assert "parasitic" in io.descriptions["z"] and "parasitic" not in io.descriptions["psi"]
    # then the condensed interface (docs/coupling.md): the drives' forces, rates and masses in, Fc and Mc out
    assert full.inputs[9:] == tuple(
        f"{q}_{k}" for q in ("F_drive", "F_drive_dot", "F_drive_ddot", "m_drive") for k in (1, 2, 3)
    )
    assert full.outputs == (*io.outputs, "Fc_1", "Fc_2", "Fc_3", "Mc_1", "Mc_2", "Mc_3")
    assert [full.units[v] for v in ("F_drive_1", "F_drive_dot_1", "m_drive_1", "Mc_1")] == [
        "N.m",
        "N.m/s",
        "kg.m2",
        "kg.m2",
    ]
    assert [full.units[v] for v in ("F_drive_3", "F_drive_ddot_3", "m_drive_3", "Fc_3")] == ["N", "N/s2", "kg", "N"]
    # the class's own are the 3PRS's: today's names and units
    assert MechanismBlock.INPUTS == Variables.of(("z", "psi", "theta"), ("linear",) * 3).inputs
    assert MechanismBlock.OUTPUTS[:9] == ("F_1", "F_2", "F_3", "x", "y", "z", "psi", "theta", "phi")


def test_a_two_drive_mechanism_block(planar):
    blk = MechanismBlock(planar)
    assert blk.INPUTS[:6] == ("rho_1", "rho_2", "rho_dot_1", "rho_dot_2", "rho_ddot_1", "rho_ddot_2")
    assert blk.OUTPUTS[:8] == ("F_1", "F_2", "x", "y", "z", "psi", "theta", "phi")
    assert len(blk.values) == 7 * 2 + 8 + 2 * 2
    # at rest, level (equal sliders): by symmetry each leg holds half the platform's weight, and a massless
    # leg pinned at both ends pushes along itself, so each slider carries m g / 2 upward (statics)
    blk.set(rho_1=0.15, rho_2=0.15)
    blk.initialize(0.0)
    out = blk.outputs()
    weight = planar["m_platform"] * planar["g"]
    assert out["F_1"] == pytest.approx(0.5 * weight, rel=1e-12) and out["F_2"] == pytest.approx(0.5 * weight, rel=1e-12)
    assert out["theta"] == pytest.approx(0.0, abs=1e-14)
    assert out["z"] == pytest.approx(0.15 + math.sqrt(0.26**2 - 0.05**2), rel=1e-12)
    # tilted (the +x side higher: theta < 0, R = Ry(theta)): the direct kinematics' pose maps back to the joints by
    # the closed form (Planar2.evaluate)
    blk.set(rho_1=0.16, rho_2=0.13, rho_dot_1=0.05, rho_ddot_2=-1.0)
    blk.do_step(0.0, 1e-3)
    out = blk.outputs()
    rho = Planar2(0.4, 0.35, 0.26).evaluate([out["z"], out["theta"]]).rho
    np.testing.assert_allclose(rho, [0.16, 0.13], atol=1e-12)
    assert out["theta"] < 0.0 and out["x"] == out["y"] == out["psi"] == out["phi"] == 0.0
    # an unreachable joint position is refused, naming the joints
    blk.set(rho_1=0.15, rho_2=0.9)
    with pytest.raises(KinematicsError, match=r"rho = \(0.15, 0.9\) m"):
        blk.do_step(1e-3, 1e-3)


def test_a_class_fixed_to_one_topology_refuses_another(planar, mechanism_params):
    cls = MechanismBlock.for_parameters(planar)
    assert cls.fixed and cls.INPUTS == MechanismBlock(planar).INPUTS
    assert MechanismBlock.for_topology(designs.describe(planar).topology) is cls
    with pytest.raises(ValueError, match="describe 3PRS .*needs its own FMU"):
        cls(mechanism_params)


def test_the_fmu_registers_the_variables_of_its_parameters(planar, tmp_path):
    """An FMU built with the scratch mechanism's parameters has its 14 inputs and 12 outputs, with their units."""
    from fmus.mechanism.fmu import MastMechanism

    (tmp_path / "parameters.json").write_text(json.dumps(planar))
    slave = MastMechanism(instance_name="planar", resources=str(tmp_path))
    names = [v.name for v in slave.vars.values()]
    assert names[:26] == [*MechanismBlock(planar).INPUTS, *MechanismBlock(planar).OUTPUTS]
    slave.setup_experiment(0.0, None, None)
    slave.enter_initialization_mode()
    slave.set_real([0, 1], [0.15, 0.15])
    slave.exit_initialization_mode()
    F = slave.get_real([14, 15])  # F_1, F_2 after the 14 inputs
    assert F == pytest.approx([0.5 * planar["m_platform"] * planar["g"]] * 2, rel=1e-12)


def test_trajectory_block_for_the_coordinates():
    cls = TrajectoryBlock.for_coordinates(("z", "theta"))
    assert cls.OUTPUTS == ("z_cmd", "theta_cmd") and cls.UNITS == {"z_cmd": "m", "theta_cmd": "rad"}
    assert [p.name for p in cls.PARAMETERS] == ["z_home", "theta_home", "amplitude_z", "amplitude_theta", "frequency"]
    assert TrajectoryBlock.for_coordinates(("z", "psi", "theta")) is TrajectoryBlock
    params = {"z_home": 0.4, "theta_home": 0.0, "amplitude_z": 0.01, "amplitude_theta": 0.02, "frequency": 2.0}
    assert TrajectoryBlock.for_parameters(params) is cls
    blk = cls(params)
    blk.initialize(0.0)
    blk.do_step(0.0, 0.125)  # a quarter period: the crest of the sine
    assert blk.values == [pytest.approx(0.41, rel=1e-15), pytest.approx(0.02, rel=1e-15)]
    with pytest.raises(ValueError, match="'q1'"):
        TrajectoryBlock.for_coordinates(("z", "q1"))


def _system(params):
    """A system of the scratch mechanism, two actuators feeding its joints, pose command inputs."""
    comps = {
        "mechanism": SimpleNamespace(
            name="mechanism",
            inputs=list(MechanismBlock(params).INPUTS),
            outputs=[],
            parameters=params,
            bindings=[],  # the values as the description declares them: no set converted them
            units={},
        ),
        "trajectory": SimpleNamespace(inputs=[], outputs=["z_cmd", "theta_cmd"], parameters={}),
        **{f"actuator_{k}": SimpleNamespace(inputs=[], outputs=["rho"], parameters={}) for k in (1, 2)},
    }
    connections = [
        SimpleNamespace(
            start_element=f"actuator_{k}", start_connector="rho", end_element="mechanism", end_connector=f"rho_{k}"
        )
        for k in (1, 2)
    ]
    return SimpleNamespace(components=comps, connections=connections, system_inputs=["z_cmd", "theta_cmd"])


def test_motion_and_admissibility_on_the_system_coordinates(planar):
    system = _system(planar)
    assert system_axes(system) == ("z", "theta")
    motion = SineMotion("theta", 0.05, 1.0)
    bind(motion, system_axes(system), "the 2PRR system")
    assert motion.reads == ["mechanism.z", "mechanism.theta"]
    motion.start(0.0, {"mechanism.z": 0.405, "mechanism.theta": 0.0}.get)
    assert motion(0.25) == [0.405, pytest.approx(0.05, rel=1e-15)]
    step = PoseStep({"z": 0.01})
    bind(step, ("z", "theta"))
    assert step.reads == ["mechanism.z", "mechanism.theta"]
    # a coordinate the system lacks: refused, naming it and the system's
    with pytest.raises(
        ValueError,
        match=r"motion axis 'psi': the 2PRR system has no such coordinate; its "
        r"mechanism's coordinates are z, theta",
    ):
        bind(SineMotion("psi", 0.01, 1.0), system_axes(system), "the 2PRR system")
    with pytest.raises(ValueError, match="pose step 'psi'"):
        bind(PoseStep({"psi": 0.01}), ("z", "theta"))
    # the admissibility check: the strokes of the two actuators, the limit named per coordinate with its unit
    params = {
        "mechanism": planar,
        **{f"actuator_{k}": {"rho_min": 0.0, "rho_max": 0.3} for k in (1, 2)},
        "trajectory": {
            "z_home": 0.405,
            "theta_home": 0.0,
            "amplitude_z": 0.0,
            "amplitude_theta": 0.3,
            "frequency": 1.0,
        },
    }
    home = [0.15 + math.sqrt(0.26**2 - 0.05**2), 0.0]
    check_commands(system, params, home, [[home[0], 0.05], [home[0], -0.05]])  # inside: no error
    with pytest.raises(
        CommandError,
        match=r"theta_cmd = 0.6 rad .*carriage 1 would be at rho_1 = .* m, beyond the "
        r"stroke \[0, 0.3\] m of actuator_1.*largest reachable theta_cmd .* rad$",
    ):
        check_commands(system, params, home, [[home[0], 0.6]])
    with pytest.raises(CommandError, match=r"z_cmd = 0.6 m .*largest reachable z_cmd on the way .* is 0.55\d* m"):
        check_commands(system, params, home, [[0.6, 0.0]])
    extremes = trajectory_extremes(system, params, 0.0, 1.0)
    assert extremes == ([0.405, 0.0], [[0.405, -0.3], [0.405, 0.3]])


def test_the_trajectory_fmu_commands_a_description_s_coordinates_python_and_native(tmp_path):
    """MastTrajectory built with the 6-PUS's home pose (six coordinates): its Python and native FMUs have the six
    outputs <c>_cmd and give home + amplitude sin(2 pi f t), written out here."""
    from fmpy import simulate_fmu

    from fmus.mechanism.designs import description
    from mast.core.build import FMUS, build_fmu
    from mast.core.native.build import build_native_fmu

    top = description("6PUS").describe(masses=False).topology
    amplitudes = [0.001 * (k + 1) for k in range(top.n)]
    params = {
        **{f"{c}_home": v for c, v in zip(top.names, top.home)},
        **{f"amplitude_{c}": a for c, a in zip(top.names, amplitudes)},
        "frequency": 2.0,
    }
    spec = next(s for s in FMUS if s.model_identifier == "MastTrajectory")
    python = build_fmu(spec, tmp_path, parameters=params)
    native = build_native_fmu("MastTrajectory", python, tmp_path / "native", params)
    for fmu in (python, native):
        result = simulate_fmu(str(fmu), stop_time=0.2, output_interval=0.01)
        assert result.dtype.names == ("time", *(f"{c}_cmd" for c in top.names))
        for c, home, a in zip(top.names, top.home, amplitudes):
            expected = [home + a * math.sin(2.0 * math.pi * 2.0 * t) for t in result["time"]]
            np.testing.assert_allclose(result[f"{c}_cmd"], expected, rtol=1e-14, atol=1e-16, err_msg=f"{fmu}: {c}")
