"""The controller alternatives (issue 7): workspace control, computed torque, torque feed-forward.

Each is checked against an expectation computed another way:
- the reference differentiator against the derivatives of polynomials;
- the controller's inverse dynamic model against the plant's forward simulation;
- computed torque with an exact model against the closed-form second-order error response,
  and with an unknown payload against the statics of the payload's weight;
- workspace control against the joint cascade (itself checked against python-control in
  test_controller.py) run with the pose direction's gain;
- feed-forward against the plain cascade (zero weights: the same numbers).
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from docs_figures import figures

from fmus.common.parameters import ParameterError
from fmus.controller.computed_torque import ComputedTorqueController
from fmus.controller.inverse_model import InverseModel
from fmus.controller.reference import rates
from fmus.controller.workspace import WorkspaceController
from fmus.mechanism.kinematics import KinematicsError
from mast.core.build import default_parameters
from mast.core.controllers import CONTROLLERS, variant_ssd
from mast.core.motion import PoseStep, SineMotion
from mast.core.run import simulate
from mast.core.ssp import read_ssd

JOINT = [f"controller.rho_cmd_{j}" for j in (1, 2, 3)] + [f"actuator_{j}.rho" for j in (1, 2, 3)]


@pytest.fixture(scope="module")
def systems(tmp_path_factory):
    """The four controller systems, built (FMUs and SSPs)."""
    from mast.core.build import FMUS, build_fmu, build_ssp

    out = tmp_path_factory.mktemp("controllers")
    needed = {"MastActuator", "MastMechanism"} | {c.model_identifier for c in CONTROLLERS}
    for spec in FMUS:
        if spec.model_identifier in needed:
            build_fmu(spec, out / "fmus")
    return {c.name: build_ssp(c.ssd, out / "fmus", out / "ssp") for c in CONTROLLERS}


def joint_errors(result) -> np.ndarray:
    s = result.signals
    return np.array([s[f"controller.rho_cmd_{j}"] - s[f"actuator_{j}.rho"] for j in (1, 2, 3)])


def controller_params(name: str) -> dict:
    """The controller's values in its system: its own parameters of the sets bound to it."""
    c = next(c for c in CONTROLLERS if c.name == name)
    return default_parameters(c.model_identifier, c.ssd)


# ----------------------------------------------------------------------------- the systems
def test_controller_systems_are_up_to_date_and_differ_only_in_the_controller():
    default = read_ssd(CONTROLLERS[0].ssd)
    for c in CONTROLLERS[1:]:
        assert c.ssd.read_bytes() == variant_ssd(c), f"{c.ssd.name} is stale: run python -m mast.core.variants"
        system = read_ssd(c.ssd)
        assert system.connections == default.connections
        for name, comp in system.components.items():
            ref = default.components[name]
            assert (comp.inputs, comp.outputs, comp.step_size) == (ref.inputs, ref.outputs, ref.step_size)
            if name != "controller":
                assert (comp.source, comp.parameters) == (ref.source, ref.parameters)
        assert system.components["controller"].source == f"resources/{c.model_identifier}.fmu"


def test_model_based_controllers_bind_the_plants_values():
    """Exact by default: every value the plant's sets give the actuators and the mechanism reaches the model."""
    system = read_ssd(next(c for c in CONTROLLERS if c.name == "computed_torque").ssd)
    ctl = system.components["controller"].parameters
    act, mech = system.components["actuator_1"].parameters, system.components["mechanism"].parameters
    names = {p.name for p in ComputedTorqueController.PARAMETERS}
    for source, shadowed in ((act, {"L"}), (mech, set())):
        for k in names & set(source) - shadowed:
            assert ctl[k] == source[k], k
    assert ctl["L"] == mech["L"]  # the leg length wins over the motor inductance of the actuator's set


def test_fmus_reproduce_the_direct_composition(systems):
    motion = dict(axis="psi", amplitude=math.radians(0.5), frequency=3.0)
    for name, ssp in systems.items():
        fmi = simulate(ssp, SineMotion(**motion), 0.15, record=JOINT)
        direct = simulate(ssp, SineMotion(**motion), 0.15, record=JOINT, direct=True)
        for key in JOINT:
            np.testing.assert_allclose(fmi.signals[key], direct.signals[key], rtol=0, atol=1e-12, err_msg=name)


# ----------------------------------------------------------------------------- the reference
class Reference:
    """The last four samples of one axis' reference, newest first, and their rates (``rates``), as the
    controllers' tick keeps them."""

    def __init__(self, T: float) -> None:
        self.T, self.samples = T, []

    def update(self, r: float) -> tuple[float, float]:
        self.samples = [r, *self.samples][:4]
        return rates(len(self.samples), *(self.samples + [0.0] * 4)[:4], self.T)


def test_reference_derivatives_are_exact_for_cubics():
    T = 1e-3
    refs = [Reference(T) for _ in range(3)]
    coef = [(0.1, 0.02, -3.0, 40.0), (0.2, -0.05, 1.5, 0.0), (0.15, 0.0, 0.0, -7.0)]  # c0 + c1 t + c2 t^2 + c3 t^3

    def at(t, c, d=0):
        return (
            [c[1] + 2 * c[2] * t + 3 * c[3] * t * t, 2 * c[2] + 6 * c[3] * t][d - 1]
            if d
            else c[0] + c[1] * t + c[2] * t * t + c[3] * t**3
        )

    for k in range(8):
        t = 0.01 + k * T
        rho_dot, rho_ddot = zip(*(ref.update(at(t, c)) for ref, c in zip(refs, coef)))
        if k == 0:
            assert rho_dot == (0.0,) * 3 and rho_ddot == (0.0,) * 3
        if k >= 3:
            np.testing.assert_allclose(rho_dot, [at(t, c, 1) for c in coef], rtol=1e-6, atol=1e-9)
            np.testing.assert_allclose(rho_ddot, [at(t, c, 2) for c in coef], rtol=1e-5, atol=1e-4)


def test_reference_error_on_a_sine_is_second_order_in_the_step():
    """At one instant t, 10 Hz: the acceleration error is -(11/12) T^2 times the fourth derivative, to leading order."""
    w, t = 2 * math.pi * 10.0, 0.0123
    errors = []
    for T in (1e-3, 5e-4):
        ref = Reference(T)
        for k in range(4):
            rho_ddot = ref.update(math.sin(w * (t - (3 - k) * T)))[1]
        errors.append(rho_ddot + w * w * math.sin(w * t))
        assert errors[-1] == pytest.approx(-11 / 12 * T * T * w**4 * math.sin(w * t), rel=0.1)
    assert abs(errors[0]) < 0.01 * w * w


# ----------------------------------------------------------------------------- the inverse model
def test_inverse_model_matches_the_plants_forward_simulation(systems):
    """Motor torques the controller's model computes from the plant's own motion (rho, rho_dot, rho_ddot)
    equal the torques the forward simulation of actuators and mechanism needed for it."""
    rec = [f"actuator_{j}.{s}" for j in (1, 2, 3) for s in ("rho", "rho_dot", "rho_ddot", "tau_m")]
    res = simulate(
        systems["joint"], SineMotion("theta", math.radians(1.0), 2.0), 1.0, record=rec, direct=True, record_step=1e-3
    )
    model = InverseModel(ComputedTorqueController(controller_params("computed_torque")).params)
    s = res.signals
    window = res.time > 0.3
    got = np.array(
        [
            model.torques(*[[s[f"actuator_{j}.{q}"][k] for j in (1, 2, 3)] for q in ("rho", "rho_dot", "rho_ddot")])
            for k in np.flatnonzero(window)
        ]
    ).T
    want = np.array([s[f"actuator_{j}.tau_m"][window] for j in (1, 2, 3)])
    for j in range(3):
        rms = np.sqrt(np.mean(want[j] ** 2))
        assert np.sqrt(np.mean((got[j] - want[j]) ** 2)) < 0.03 * rms, j


# ----------------------------------------------------------------------------- computed torque
STEP = {"z": 0.0005, "psi": 0.002, "theta": -0.002}


def test_computed_torque_error_follows_the_chosen_poles(systems):
    """Exact model: each joint error obeys e'' + 2 zeta w e' + w^2 e = 0 from its own initial value, however
    the step couples the joints, for two pole choices (critically damped and underdamped)."""
    for omega_n, zeta in ((2 * math.pi * 10.0, 1.0), (2 * math.pi * 6.0, 0.5)):
        res = simulate(
            systems["computed_torque"],
            PoseStep(STEP),
            0.5,
            record=JOINT,
            direct=True,
            record_step=1e-3,
            parameters={"controller": {"omega_n": omega_n, "zeta": zeta}},
        )
        e, t = joint_errors(res), res.time
        wd = omega_n * math.sqrt(1.0 - zeta**2) if zeta < 1 else 0.0
        if zeta < 1:
            shape = np.exp(-zeta * omega_n * t) * (np.cos(wd * t) + zeta * omega_n / wd * np.sin(wd * t))
        else:
            shape = (1.0 + omega_n * t) * np.exp(-omega_n * t)
        for j in range(3):
            assert abs(e[j, 0]) > 1e-4
            assert np.max(np.abs(e[j] - e[j, 0] * shape)) < 0.02 * np.max(np.abs(e[:, 0])), (omega_n, zeta, j)


def test_computed_torque_with_an_unknown_payload_settles_where_statics_say(systems):
    """A payload the controller does not know: no integral action, so the joints settle at e_ss with
    K_P M e_ss = the payload's weight on the joints; for vertical guides those forces add up to m g."""
    m = 3.0
    res = simulate(
        systems["computed_torque"],
        PoseStep({"z": 0.0005}),
        0.6,
        record=JOINT,
        direct=True,
        parameters={"mechanism": {"m_payload": m}},
    )
    e_ss = joint_errors(res)[:, -1]
    ctl = ComputedTorqueController(controller_params("computed_torque"))
    model = ctl.model
    rho = [res.signals[f"actuator_{j}.rho"][-1] for j in (1, 2, 3)]
    M = model.engine.inverse_dynamics(rho, [0.0] * 3, [0.0] * 3).M + model.J / model.i_R**2 * np.eye(3)
    forces = ctl.K_P * (M @ e_ss)
    assert forces.sum() == pytest.approx(m * 9.81, rel=0.02)
    assert np.all(forces > -1e-3 * m * 9.81)  # the weight pushes every slider down (or not at all)
    # without the payload the error vanishes
    exact = simulate(systems["computed_torque"], PoseStep({"z": 0.0005}), 0.6, record=JOINT, direct=True)
    assert np.max(np.abs(joint_errors(exact)[:, -1])) < 1e-3 * np.max(np.abs(e_ss))


def test_computed_torque_has_no_velocity_mode():
    ctl = ComputedTorqueController(controller_params("computed_torque"))
    with pytest.raises(ValueError, match="modes are pose, joint, current"):
        ctl.set_mode("velocity", (0.0, 0.0, 0.0))


# ----------------------------------------------------------------------------- workspace control
def test_workspace_gains_shape_each_pose_direction(systems):
    """Gains per pose direction: the z error of a z + psi step follows the joint cascade's z step with k_v,
    the psi error the joint cascade's psi step with 3 k_v (independent runs, the cascade's own code).
    Superposition needs a linear plant: the actuators' Coulomb friction is off in every run."""
    k_v = float(controller_params("workspace")["k_v"])
    linear = {f"actuator_{j}": {"tau_c": 0.0} for j in (1, 2, 3)}
    poses = ["mechanism.z", "mechanism.psi", "mechanism.theta"]
    steps = {"z": 0.0002, "psi": 0.001}
    work = simulate(
        systems["workspace"],
        PoseStep(steps),
        0.4,
        record=poses + ["z_cmd", "psi_cmd"],
        direct=True,
        parameters={"controller": {"k_v_scale_psi": 3.0}, **linear},
    )
    for axis, gain in (("z", k_v), ("psi", 3 * k_v)):
        joint = simulate(
            systems["joint"],
            PoseStep({axis: steps[axis]}),
            0.4,
            record=poses + [f"{axis}_cmd"],
            direct=True,
            parameters={"controller": {"k_v": gain}, **linear},
        )
        e_work = work.signals[f"{axis}_cmd"] - work.signals[f"mechanism.{axis}"]
        e_joint = joint.signals[f"{axis}_cmd"] - joint.signals[f"mechanism.{axis}"]
        assert np.max(np.abs(e_work - e_joint)) < 0.01 * steps[axis], axis
    theta = work.signals["mechanism.theta"] - work.signals["mechanism.theta"][0]
    assert np.max(np.abs(theta)) < 0.01 * steps["psi"]  # decoupled: no theta motion


def test_workspace_controller_in_joint_mode_refuses_a_joint_command_it_cannot_reach():
    """In "joint" mode the pose target is the direct kinematics of rho_cmd (the tick's joint-mode branch, which
    only Python runs): an unreachable rho_cmd stops the tick with the message naming it and the tick's time."""
    ctl = WorkspaceController(controller_params("workspace"), "ws")
    ctl.set(z_cmd=0.40, rho_1=0.15, rho_2=0.15, rho_3=0.15)
    ctl.set_mode("joint", (0.15, 0.15, 0.15))
    ctl.initialize(0.0)
    ctl.do_step(0.0, 1e-3)
    assert [ctl.get(f"rho_cmd_{j}") for j in (1, 2, 3)] == [0.15, 0.15, 0.15]
    ctl.set_mode("joint", (0.15, 0.9, 0.15))
    with pytest.raises(
        KinematicsError,
        match=r"^ws: direct kinematics of the joint command rho = \(0\.15, 0\.9, 0\.15\) m "
        r"failed at t = 0\.001 s: direct kinematics did not converge",
    ):
        ctl.do_step(1e-3, 1e-3)


def test_workspace_control_with_unit_gains_is_the_joint_cascade_for_small_motions(systems):
    motion = SineMotion("theta", math.radians(0.3), 2.0)
    work = simulate(systems["workspace"], motion, 0.6, record=JOINT, direct=True)
    joint = simulate(systems["joint"], SineMotion("theta", math.radians(0.3), 2.0), 0.6, record=JOINT, direct=True)
    assert np.max(np.abs(joint_errors(work) - joint_errors(joint))) < 0.01 * np.max(np.abs(joint_errors(joint)))


# ----------------------------------------------------------------------------- feed-forward
def test_feedforward_with_zero_weights_is_the_cascade(systems):
    motion = dict(axis="z", amplitude=0.005, frequency=2.0)
    ff = simulate(
        systems["feedforward"],
        SineMotion(**motion),
        0.3,
        record=JOINT,
        direct=True,
        parameters={"controller": {"k_ff_v": 0.0, "k_ff_tau": 0.0}},
    )
    joint = simulate(systems["joint"], SineMotion(**motion), 0.3, record=JOINT, direct=True)
    np.testing.assert_array_equal(joint_errors(ff), joint_errors(joint))


def test_feedforward_removes_most_of_the_tracking_error(systems):
    """With the exact model the feedback only corrects the reference estimate and sampling: at 2 Hz the
    cascade lags by tens of percent of the amplitude, the feed-forward leaves about a percent."""
    motion = dict(axis="z", amplitude=0.005, frequency=2.0)
    errs = {}
    for name in ("joint", "feedforward"):
        res = simulate(systems[name], SineMotion(**motion), 1.0, record=JOINT, direct=True)
        errs[name] = np.max(np.abs(joint_errors(res)[:, res.time > 0.5]))
    assert errs["joint"] > 0.3 * 0.005
    assert errs["feedforward"] < 0.02 * 0.005


# ----------------------------------------------------------------------------- bad input
def test_feedforward_weight_out_of_range_is_named():
    params = {**controller_params("feedforward"), "k_ff_tau": 3.0}
    from fmus.controller.feedforward import FeedForwardController

    with pytest.raises(ParameterError, match="k_ff_tau"):
        FeedForwardController(params)


# ----------------------------------------------------------------------------- mast compare --controller
def test_compare_controllers_tabulates_and_plots_with_an_unknown_payload(systems, tmp_path):
    from mast.cli import main as cli_main

    fmus = Path(systems["joint"]).parents[1] / "fmus"
    out = tmp_path / "cmp"
    # docs/figures.py's short variant (joint and computed_torque, z at 1 and 3 Hz, 3 kg), whose figures
    # docs/controller.md states
    code = cli_main(figures.controllers_short_argv(out, fmus))
    assert code == 0
    for name in (
        "comparison.csv",
        "runs.csv",
        "comparison.json",
        "comparison.md",
        "bode.png",
        "motion_z.png",
        "systems/computed_torque.ssp",
    ):
        assert (out / name).stat().st_size > 100, name
    data = json.loads((out / "comparison.json").read_text())
    labels = [c["label"] for c in data["controllers"]]
    assert labels == ["joint", "computed_torque", "joint +3 kg", "computed_torque +3 kg"]
    rows = {(r["controller"], r["motion"]): r for r in data["summary"]}
    # the model-based controller tracks better as designed, and loses some of it to the payload it does not know
    assert rows[("computed_torque", "z")]["tracking_peak"] < 0.2 * rows[("joint", "z")]["tracking_peak"]
    robust = {r["controller"]: r for r in data["robustness"]}
    # no integral action: the unknown weight leaves an offset at low frequency; the cascade integrates it away
    assert robust["computed_torque"]["tracking_peak_f_min_ratio"] > 2.0
    assert robust["joint"]["tracking_peak_f_min_ratio"] < 1.2
    assert list(csv.DictReader(open(out / "comparison.csv")))[0]["controller"] == "joint"
    problems = figures.check({"controllers_short": figures.controllers_values(data)})
    assert not problems, "\n".join(problems)


def test_compare_rejects_an_unknown_controller(tmp_path):
    from mast.analyses.compare import compare

    with pytest.raises(FileNotFoundError, match="no such file or a controller name"):
        compare(controllers=["cascade_pid"], out=tmp_path)
