"""The 6-UPS hexapod as a system (ssp/MAST_6UPS.ssd, docs/designs/6ups.md): six actuator FMUs, its mechanism FMU
Mast6UPS and controller Mast6UPSController (Python FMUs; the native runtime generates the 3PRS's models only yet).

Its legs are electric cylinders of the paper's kind: the paper's motor, gearhead and drive turning a ball screw of
16 mm lead (transmission_screw.ssv, actuator_screw.ssv). With the paper's belt axis in their place the initial loop
through the actuators and the mechanism has the gain of the mechanism's joint-space mass over the actuator's
load-side mass, 11.7 kg (the hexapod's stiffest horizontal modes at home) over 3.6 kg (J_guide (2 pi / p)^2): the
master's Jacobi passes diverge and its Newton solve (mast.core.initial) finds the consistent initial point.
"""

from __future__ import annotations

import math

import newton_euler as ne
import numpy as np
import pytest
from conftest import build_mechanism_system
from test_hexapod import HEX, oracle

#: the ball screw's lead [m] and spin inertia [kg m2] (ssp/resources/transmission_screw.ssv, actuator_screw.ssv)
SCREW_LEAD = 0.016
J_SCREW = math.pi * 7850.0 * 0.36 * 0.016**4 / 32


def docs_figures():
    """docs/figures.py as a module (the figures the pages state)."""
    import importlib.util
    import sys
    from pathlib import Path

    spec = importlib.util.spec_from_file_location("docs_figures", Path(__file__).parents[1] / "docs" / "figures.py")
    module = sys.modules[spec.name] = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


T_MECH = 1e-3  # s: the mechanism's full-update period in the systems (attached.ssv)


def worst_against_the_oracle(mech, res, stride: int) -> float:
    """The largest force difference between the mechanism's outputs in a run recorded every 100 us and the oracle's,
    relative to the largest force: the outputs at t + h are the full update (direct kinematics, M, b) of the
    actuators' positions and velocities at the last update instant u (t0 + k T_mech, the pose held since) with the
    accelerations at t (F = M rho_ddot(t) + b); the pose is checked as the oracle's direct kinematics of rho(u).
    Every ``stride``-th record (prime to the 10 steps of an update period: every phase of it is checked)."""
    rho, rd, rdd = (
        np.column_stack([res[f"actuator_{k}.{v}"] for k in range(1, 7)]) for v in ("rho", "rho_dot", "rho_ddot")
    )
    F = np.column_stack([res[f"mechanism.F_{k}"] for k in range(1, 7)])
    q = np.column_stack([res[f"mechanism.{c}"] for c in ne.POSE])
    ticks = np.rint((res.time - res.time[0]) / 1e-4).astype(int)
    assert np.all(np.diff(ticks) == 1)  # every 100 us
    every = round(T_MECH / 1e-4)
    assert math.gcd(stride, every) == 1
    worst = 0.0
    for k in range(0, len(res.time) - 1, stride):
        u = k - ticks[k] % every
        np.testing.assert_allclose(ne.joints(mech, q[k + 1]), rho[u], rtol=0.0, atol=1e-10)
        worst = max(worst, float(np.max(np.abs(ne.forces(mech, q[k + 1], rd[u], rdd[k]) - F[k + 1]))))
    return worst / np.max(np.abs(F))


@pytest.fixture(scope="module")
def hexapod_system(tmp_path_factory):
    """MAST_6UPS.ssp built with its FMUs (the Python ones)."""
    return build_mechanism_system("6UPS", tmp_path_factory.mktemp("hexapod"))


def test_the_6ups_system_binds_its_description_everywhere():
    """ssp/MAST_6UPS.ssd (python -m mast.core.variants): the mechanism gets the description's values, the controller
    its geometry and the screw's lead, six actuators the stroke, no carriage and the screw; six command inputs, seven
    connections per drive."""
    from mast.core.designs import design, variant_ssd
    from mast.core.ssp import read_ssd

    d = design("6UPS")
    assert d.ssd.read_bytes() == variant_ssd(d), f"{d.ssd.name} is stale: run python -m mast.core.variants"
    system = read_ssd(d.ssd)
    mech = dict(system.components["mechanism"].parameters)
    assert (mech.pop("kinematics"), mech.pop("attached"), mech.pop("T_mech")) == (
        "6UPS",
        1,
        1e-3,
    ) and mech == HEX.values()
    ctrl = system.components["controller"]
    assert ctrl.source.endswith("Mast6UPSController.fmu")
    assert {k: ctrl.parameters[k] for k in HEX.kinematic} == {k: HEX.values()[k] for k in HEX.kinematic}
    assert set(HEX.kinematic) == {"R_b", "r", "gamma_b", "gamma_p"} and "H" not in ctrl.parameters
    assert ctrl.parameters["p"] == SCREW_LEAD
    for k in range(1, 7):
        act = system.components[f"actuator_{k}"].parameters
        assert (act["M_load"], act["g_guide"], act["rho_min"], act["rho_max"], act["rho_0"]) == pytest.approx(
            (0.0, 0.0, 0.45, 0.75, 0.6), abs=1e-15
        )
        assert act["p"] == SCREW_LEAD and act["n_dof"] == 1
        assert act["J_guide"] == pytest.approx(J_SCREW + 2 * 0.5 * 2700 * math.pi * 0.016**4 * 0.015, rel=0.01)
    assert "actuator_7" not in system.components
    assert system.system_inputs == [f"{c}_cmd" for c in ne.POSE]
    assert len(system.connections) == 6 + 12 * 6  # 12 per drive: docs/interfaces.md, the connector convention


def test_the_6ups_fmus_have_the_description_s_parameters(hexapod_system):
    from mast.core.components import fmu_parameters

    fmus = hexapod_system.parent.parent / "fmus"
    mech = fmu_parameters(fmus / "Mast6UPS.fmu")
    assert list(mech) == ["kinematics", *HEX.parameters, "attached", "T_mech"]
    ctrl = fmu_parameters(fmus / "Mast6UPSController.fmu")
    assert set(HEX.kinematic) <= set(ctrl) and ctrl["kinematics"] == "6UPS"


def test_with_the_belt_axis_the_system_starts_at_rest_without_an_initial_loop(hexapod_system):
    """The paper's belt axis on every leg (its transmission and manufacturer sets in place of the screw's): the
    joint-space mass at home (the oracle's, by finite differences) exceeds the actuator's load-side mass 3.6 kg, a
    loop gain above 1 that plain Jacobi passes of an initial loop would not solve. There is none: every actuator
    reports its carriage at rest at initialisation (acceleration 0 until its first step, docs/interfaces.md
    Timing), so the initial point follows from the parameters, the mechanism's forces there the oracle's statics
    (the weight at home), and after the first step the carriages fall under it."""
    from mast.core.motion import SineMotion
    from mast.core.run import simulate
    from mast.core.ssv import read_values
    from mast.core.systems import SSP_SRC

    res_dir = SSP_SRC / "resources"
    belt = read_values(*(res_dir / f for f in ("transmission.ssv", "actuator_manufacturer.ssv", "actuator_6ups.ssv")))
    m_load = belt["J_guide"] * (2 * math.pi / belt["p"]) ** 2
    mech = oracle()
    res = simulate(
        hexapod_system,
        SineMotion(axis="z", amplitude=0.001, frequency=2.0, axes=ne.POSE),
        0.0002,
        {"controller": {"p": belt["p"]}, **{f"actuator_{k}": belt for k in range(1, 7)}},
        record_step=1e-4,
    )
    q0 = np.array([res[f"mechanism.{c}"][0] for c in ne.POSE])
    zero = np.zeros(6)
    joint_mass = np.column_stack([ne.forces(mech, q0, zero, e) - ne.forces(mech, q0, zero, zero) for e in np.eye(6)])
    assert np.max(np.linalg.eigvalsh(0.5 * (joint_mass + joint_mass.T))) / m_load > 3.0  # the loop gain
    rdd = np.array([[res[f"actuator_{k}.rho_ddot"][j] for k in range(1, 7)] for j in (0, 1)])
    F = np.array([[res[f"mechanism.F_{k}"][j] for k in range(1, 7)] for j in (0, 1)])
    assert np.all(rdd[0] == 0.0)  # at rest
    np.testing.assert_allclose(F[0], ne.forces(mech, q0, zero, zero), rtol=1e-9)  # the weight
    assert np.max(np.abs(rdd[1])) > 0.1 and np.all(np.sign(rdd[1]) == -np.sign(F[0]))  # the platform starts to fall


def test_the_6ups_mechanism_fmu_in_the_loop_against_the_newton_euler_oracle(hexapod_system, tmp_path):
    """A run as the system is (Python FMUs, 3 mm at 2 Hz in z, 0.2 s): the pose and the forces the mechanism reports
    for every recorded state against the oracle's kinematics and inverse dynamics at that state
    (``worst_against_the_oracle``: the full update every T_mech, the accelerations at every step); it moves; its
    summary names the six coordinates (the held ones' errors nil) and the six drives, and motion.png is drawn."""
    import json

    from mast.core.motion import SineMotion
    from mast.core.run import simulate, write_outputs

    axis, amplitude = "z", 0.003
    mech = oracle()
    motion = SineMotion(axis=axis, amplitude=amplitude, frequency=2.0, axes=ne.POSE)
    res = simulate(hexapod_system, motion, 0.2, record_step=1e-4)
    write_outputs(res, tmp_path, 0.2, motion)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert list(summary["coordinates"]) == list(ne.POSE)
    assert summary["coordinates"]["z"]["error_peak"] == summary["tracking_error_peak"] > 1e-4
    # held: x, y, psi, theta to rounding; phi to 1e-5 rad (the legs of a pair differ, the motor on the same side of
    # each, so their forces and lags do: a yaw of about 1e-6 rad)
    assert all(summary["coordinates"][c]["error_peak"] < 1e-9 for c in ("x", "y", "psi", "theta"))
    assert summary["coordinates"]["phi"]["error_peak"] < 1e-5
    assert all(summary[f"i_m_{k}_peak_A"] > 0.1 and summary[f"tau_m_{k}_peak_Nm"] > 0 for k in range(1, 7))
    assert "i_m_7_peak_A" not in summary and (tmp_path / "motion.png").stat().st_size > 10_000
    assert np.ptp(res["mechanism." + axis]) > 0.3 * amplitude  # it moves
    assert worst_against_the_oracle(mech, res, 7) < 1e-9


def test_a_6ups_system_run_balances_energy_and_carries_the_weight_at_rest(hexapod_system):
    """Over a run (docs/figures.py HEXAPOD_RUN: z, 3 mm at 2 Hz, 0.4 s): the work the n drives do on the
    mechanism, the integral of sum_k F_k rho_dot_k (the forces the mechanism returns for the actuators' motion of the
    step before), is the change of the mechanism's kinetic and potential energy computed by the oracle's bodies from
    the actuators' recorded state (direct kinematics and velocities by differences: no inverse dynamics), to the
    trapezoid rule's error bound (t - t0) h^2 / 12 max |P''| at the record step h = 100 us (measured: the gaps 8 to 15
    times inside it; the mechanism's 1 ms hold of M and b costs less). Held at home (0.4 s, the command
    still): the forces are the weight's by virtual work, J^-T dV/dq, the potential energy's gradient through the
    oracle's leg lengths. The run's figures are docs/designs/6ups.md's (`python docs/figures.py --source
    hexapod_run`)."""
    from test_hexapod import kinetic, oracle_jacobian, pose_of, potential

    from mast.core.motion import SineMotion
    from mast.core.run import simulate, summarize

    figures = docs_figures()
    axis, amplitude, frequency, stop = figures.HEXAPOD_RUN
    mech = oracle()
    motion = SineMotion(axis=axis, amplitude=amplitude, frequency=frequency, axes=ne.POSE)
    res = simulate(hexapod_system, motion, stop)
    problems = figures.check({"hexapod_run": figures.hexapod_run_values(summarize(res, stop, motion))})
    assert not problems, "\n".join(problems)
    res = simulate(hexapod_system, motion, stop, record_step=1e-4)
    n = len(res.drives())
    assert n == 6
    t = res.time
    rho, rd = (np.column_stack([res[f"actuator_{k}.{v}"] for k in range(1, n + 1)]) for v in ("rho", "rho_dot"))
    F = np.column_stack([res[f"mechanism.F_{k}"] for k in range(1, n + 1)])
    q = np.column_stack([res[f"mechanism.{c}"] for c in ne.POSE])
    power = np.einsum("ij,ij->i", F[1:], rd[:-1])  # at t[:-1]: the forces of the actuators' state there
    h = t[1] - t[0]
    work = np.concatenate(([0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * h)))
    bound = (t[:-1] - t[0]) / 12.0 * np.max(np.abs(np.diff(power, 2)))  # trapezoid: (t - t0) h^2 / 12 max|P''|

    def energy(j: int) -> float:
        pose = pose_of(mech, rho[j], q[j + 1])
        return kinetic(mech, rho[j], rd[j], pose) + potential(mech, pose)

    e0 = energy(0)
    checked = range(500, len(t) - 1, 700)
    gaps = [abs(energy(j) - e0 - work[j]) for j in checked]
    assert np.max(np.abs(power)) > 0.05 and np.max(np.abs(work)) > 1e-3  # power flows both ways, work is done
    assert all(gap <= 2.0 * bound[j] + 1e-9 for gap, j in zip(gaps, checked)), (gaps, [bound[j] for j in checked])

    still = simulate(hexapod_system, SineMotion(axis="z", amplitude=0.0, frequency=0.0, axes=ne.POSE), 0.4)
    pose = np.array([still[f"mechanism.{c}"][-1] for c in ne.POSE])
    held = np.array([still[f"mechanism.F_{k}"][-1] for k in range(1, n + 1)])
    e = 1e-5
    dV = np.array([(potential(mech, pose + e * d) - potential(mech, pose - e * d)) / (2 * e) for d in np.eye(6)])
    np.testing.assert_allclose(held, np.linalg.solve(oracle_jacobian(mech, pose, e).T, dV), rtol=0.0, atol=1e-3)


@pytest.mark.parametrize("axis, amplitude", [("x", 0.4), ("psi", math.radians(40.0))])
def test_a_pose_command_outside_the_hexapod_s_workspace_is_refused_before_the_first_step(
    hexapod_system, axis, amplitude
):
    """A sine whose extreme leaves the strokes: refused at initialization, naming the coordinate, its value and the
    reachable limit along it (a leg's stroke)."""
    from mast.core.admissible import CommandError
    from mast.core.motion import SineMotion
    from mast.core.run import simulate

    with pytest.raises(
        CommandError,
        match=rf"{axis}_cmd = .* is outside the workspace .* beyond the stroke "
        rf"\[0.45, 0.75\] m .* The (largest|smallest) reachable {axis}_cmd on the way from the home pose",
    ):
        simulate(hexapod_system, SineMotion(axis=axis, amplitude=amplitude, frequency=1.0, axes=ne.POSE), 1.0)


def test_a_seventh_coordinate_is_refused_naming_the_hexapod_s_six():
    from mast.core.motion import PoseStep, SineMotion
    from mast.core.run import motion_from_cli

    six = ", ".join(ne.POSE)
    with pytest.raises(ValueError, match=rf"coordinate 'chi': expected one of the pose components {six}"):
        motion_from_cli("chi", 1.0, 1.0, ne.POSE, "MAST_6UPS.ssp")
    with pytest.raises(ValueError, match=rf"motion axis 'chi': expected one of {six}"):
        SineMotion(axis="chi", amplitude=0.01, frequency=1.0, axes=ne.POSE)
    with pytest.raises(ValueError, match=rf"pose step 'chi' = 0.01: expected finite offsets of {six}"):
        PoseStep({"chi": 0.01}, axes=ne.POSE)


def test_a_leg_stroke_that_excludes_home_is_refused_before_the_first_step(hexapod_system):
    """actuator_3's stroke cut to 0.45 .. 0.55 m (its start moved inside it): the home pose needs leg 3 at 0.6 m;
    refused naming the actuator, the joint, its length at home and the limit."""
    from mast.core.admissible import StrokeError
    from mast.core.motion import SineMotion
    from mast.core.run import simulate

    with pytest.raises(
        StrokeError,
        match=r"actuator_3: stroke \[0.45, 0.55\] m excludes the home pose .* z = 0.540363 m"
        r".* rho_3 = 0.6 m: rho_max = 0.55 m",
    ):
        simulate(
            hexapod_system,
            SineMotion(axis="z", amplitude=0.001, frequency=1.0, axes=ne.POSE),
            0.1,
            {"actuator_3": {"rho_max": 0.55, "rho_0": 0.5}},
        )


def test_compare_sets_the_hexapod_beside_3_dof_designs_on_their_common_motions(hexapod_system):
    """`mast compare --mechanism` with the 3PRS, the 3-RPS and the 6-UPS: the motions every design has (z, psi,
    theta) are the test set, the hexapod's x, y, phi are listed as its extra motions, and its workspace is swept
    over the common ones (the others held at home), in the 3-DOF designs' unit (m deg^2)."""
    from mast.analyses.compare import Candidate, common_axes, design_workspace, extra_motions

    designs = [("z", "psi", "theta"), ("z", "psi", "theta"), ne.POSE]
    assert common_axes(designs) == ("z", "psi", "theta")
    assert [extra_motions(a, designs) for a in designs] == [(), (), ("x", "y", "phi")]
    ws = design_workspace(
        Candidate("6UPS", str(hexapod_system), "6UPS"), (0.05, math.radians(8.0)), common_axes(designs)
    )
    assert "error" not in ws, ws
    assert set(ws["ranges_through_home"]) == {"z_m", "psi_deg", "theta_deg"} and ws["volume_m_deg2"] > 100.0


# ---------------------------------------------------------------------- the 6-PUS: the paper's actuators as they are
@pytest.fixture(scope="module")
def pus_system(tmp_path_factory):
    """MAST_6PUS.ssp built with its FMUs (the Python ones)."""
    return build_mechanism_system("6PUS", tmp_path_factory.mktemp("pus"))


def test_the_6pus_system_binds_its_description_and_the_paper_s_actuators():
    """ssp/MAST_6PUS.ssd: the description's values, the controller's geometry, six actuators as the 3PRS's (the
    carriage and its weight on the vertical guide in the actuator, paper Eq. 22; the stroke from the description)."""
    from test_hexapod import PUS

    from mast.core.designs import design, variant_ssd
    from mast.core.ssp import read_ssd

    d = design("6PUS")
    assert d.ssd.read_bytes() == variant_ssd(d), f"{d.ssd.name} is stale: run python -m mast.core.variants"
    system = read_ssd(d.ssd)
    mech = dict(system.components["mechanism"].parameters)
    assert (mech.pop("kinematics"), mech.pop("attached"), mech.pop("T_mech")) == (
        "6PUS",
        1,
        1e-3,
    ) and mech == PUS.values()
    assert system.components["controller"].source.endswith("Mast6PUSController.fmu")
    mast = read_ssd(design("3PRS_T").ssd).components["actuator_1"].parameters
    for k in range(1, 7):
        act = system.components[f"actuator_{k}"].parameters
        assert act == mast  # M_load 2.27 kg, g_guide 9.81 m/s2, stroke 0..0.3 m, rho_0 0.15 m
    assert len(system.connections) == 6 + 12 * 6  # 12 per drive: docs/interfaces.md, the connector convention


@pytest.mark.parametrize("axis, amplitude", [("x", 0.005), ("phi", math.radians(0.8))])
def test_a_6pus_run_against_the_newton_euler_oracle(pus_system, axis, amplitude):
    """The system runs as it is (Python FMUs, 2 Hz, 1 s) and tracks as the MAST does; the mechanism's pose and forces
    at every recorded state (100 us) against the oracle's (``worst_against_the_oracle``)."""
    from test_hexapod import pus_oracle

    from mast.core.motion import SineMotion
    from mast.core.run import simulate

    mech = pus_oracle()
    motion = SineMotion(axis=axis, amplitude=amplitude, frequency=2.0, axes=ne.POSE)
    res = simulate(pus_system, motion, 1.0, record_step=1e-4)
    moved = res["mechanism." + axis] - res["mechanism." + axis][0]
    assert 0.7 * amplitude < np.max(np.abs(moved)) < 1.2 * amplitude  # it follows the sine (the MAST's lag)
    assert worst_against_the_oracle(mech, res, 37) < 1e-9
