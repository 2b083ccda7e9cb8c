"""The 3-RPS as a system (issue 25): its mechanism block's and controllers' parameters from its description file,
its FMU, its design SSD, its run beside the 3PRS's.

Physics against independent routes: the forces the system's mechanism reports at rest against the Newton-Euler
oracle (tests/newton_euler.py), an energy balance over a run from the recorded joint motion and forces.
"""

from __future__ import annotations

import math

import pytest
from conftest import build_mechanism_system

from fmus.common.parameters import ParameterError
from fmus.controller.feedforward import FeedForwardController
from fmus.controller.model import ControllerBlock
from fmus.mechanism import designs
from fmus.mechanism.description import load
from fmus.mechanism.model import MechanismBlock

RPS = load("3RPS")


def rps_parameters(**changes) -> dict:
    """The mechanism block's parameters of the 3-RPS: the description's values, ``kinematics``, ``attached``."""
    return {"kinematics": "3RPS", **RPS.values(), "attached": 1, **changes}


def test_the_mechanism_block_takes_the_parameters_of_its_description():
    """Name, unit, description = the file's source, range where the file gives one; kinematics, attached, T_mech."""
    block = MechanismBlock(rps_parameters(), "rps")
    names = [p.name for p in block.PARAMETERS]
    assert names == ["kinematics", *RPS.parameters, "attached", "T_mech"]
    by_name = {p.name: p for p in block.PARAMETERS}
    for name, p in RPS.parameters.items():
        assert (by_name[name].unit, by_name[name].description) == (p.unit, p.source)
    assert (by_name["m_carriage"].minimum, by_name["g"].maximum) == (0.0, 100.0)
    assert by_name["x_cylinder"].minimum == -math.inf  # the file gives it no range
    assert "3RPS" in by_name["kinematics"].description
    with pytest.raises(ParameterError, match=r"rps: parameter 'm_carriage' = -1.0: expected a float in \[0, inf\]"):
        MechanismBlock(rps_parameters(m_carriage=-1.0), "rps")
    with pytest.raises(ParameterError, match=r"unknown parameter\(s\) H; expected names: .*R_b"):
        MechanismBlock(rps_parameters(H=0.4), "rps")
    with pytest.raises(ParameterError, match=r"missing parameter\(s\) R_b"):
        MechanismBlock({k: v for k, v in rps_parameters().items() if k != "R_b"}, "rps")


def test_the_3prs_schema_is_its_description_file_s():
    """The 3PRS keeps its declared schema (its FMU's parameters: names, order, units); those are its file's."""
    prs = designs.description("3PRS")
    schema = MechanismBlock.PARAMETERS
    assert designs.parameters_for(schema, "3PRS") == schema
    declared = {p.name: p.unit for p in schema if p.name not in ("kinematics", "attached", "T_mech")}
    assert declared == {n: p.unit for n, p in prs.parameters.items()}
    assert tuple(p.name for p in designs.KINEMATIC_PARAMETERS[1:]) == prs.kinematic


def test_an_fmu_class_of_the_3rps_has_its_parameters():
    """Block.for_parameters (what the FMU registers): the 3-RPS's schema; the 3PRS's unchanged."""
    cls = MechanismBlock.for_parameters(rps_parameters())
    assert cls.fixed and cls.MECHANISM == "3RPS" and [p.name for p in cls.PARAMETERS][1] == "R_b"
    assert cls.for_parameters(rps_parameters()) is cls
    block = cls(rps_parameters(), "rps")
    block.set(rho_1=0.41, rho_2=0.41, rho_3=0.41)
    block.initialize(0.0)
    assert block.outputs()["z"] == pytest.approx(RPS.describe().topology.home[0], rel=1e-12)
    prs = MechanismBlock.for_parameters({"kinematics": "3PRS", **designs.description("3PRS").values(), "attached": 1})
    assert prs.PARAMETERS == MechanismBlock.PARAMETERS and prs.MECHANISM == "3PRS"


@pytest.mark.parametrize("kind", [ControllerBlock, FeedForwardController])
def test_the_controllers_kinematic_model_takes_the_geometry_of_its_description(kind):
    """A controller's geometry set is its description's kinematic parameters (R_b, r, alpha_k for the 3-RPS); a
    feed-forward controller's inverse model also takes the bodies' (its mass sets)."""
    base = {p.name for p in kind.PARAMETERS}
    cls = kind.for_parameters({"kinematics": "3RPS", **{n: RPS.parameters[n].value for n in RPS.kinematic}})
    names = [p.name for p in cls.PARAMETERS]
    assert cls.__name__ == kind.__name__ and cls.MECHANISM == "3RPS"
    assert set(RPS.kinematic) <= set(names) and "H" not in names and "L" not in names
    if "m_leg" in base:
        assert "m_carriage" in names and "m_leg" not in names and "attached" in names
    else:
        assert "m_carriage" not in names
    assert kind.for_parameters({"kinematics": "3PRS", **designs.description("3PRS").values()}) is kind


# ----------------------------------------------------------------------------- its system
def test_the_stroke_sets_are_the_descriptions_and_home_is_mid_stroke():
    """rho_min, rho_max from the drives' stroke; rho_0 its middle, where the home pose puts every drive (the legs'
    inverse kinematics at home, a second route); the 3-RPS's actuators carry no carriage (M_load = g_guide = 0)."""
    from mast.core import ssv
    from mast.core.systems import SSP_SRC

    for name, file in (("stroke_3prs", "3PRS_T"), ("actuator_3rps", "3RPS")):
        values = {k: p.value for k, p in ssv.read(SSP_SRC / "resources" / f"{name}.ssv").parameters.items()}
        desc = designs.description("3PRS") if file == "3PRS_T" else RPS
        ((lo, hi),) = {leg.stroke for leg in desc.legs}
        assert (values["rho_min"], values["rho_max"]) == (lo, hi)
        described = desc.describe(masses=False)
        home = described.evaluate(list(described.topology.home)).rho
        assert home == pytest.approx([values["rho_0"]] * 3, abs=1e-12)
    assert (values["M_load"], values["g_guide"]) == (0.0, 0.0)


def test_the_3rps_system_binds_its_description_everywhere():
    """ssp/MAST_3RPS.ssd (python -m mast.core.variants): its mechanism gets the description's values, its controller
    the geometry, its actuators the stroke and no carriage; three actuators, the connector convention."""
    from mast.core.designs import MECHANISMS, variant_ssd
    from mast.core.ssp import read_ssd

    d = next(d for d in MECHANISMS if d.name == "3RPS")
    assert d.ssd.read_bytes() == variant_ssd(d), f"{d.ssd.name} is stale: run python -m mast.core.variants"
    system = read_ssd(d.ssd)
    mech = dict(system.components["mechanism"].parameters)
    assert (mech.pop("kinematics"), mech.pop("attached"), mech.pop("T_mech")) == (
        "3RPS",
        1,
        1e-3,
    ) and mech == RPS.values()
    ctrl = system.components["controller"]
    assert ctrl.source.endswith("Mast3RPSController.fmu")
    assert {k: ctrl.parameters[k] for k in RPS.kinematic} == {k: RPS.values()[k] for k in RPS.kinematic}
    assert "H" not in ctrl.parameters
    for k in (1, 2, 3):
        act = system.components[f"actuator_{k}"].parameters
        assert (act["M_load"], act["g_guide"], act["rho_min"], act["rho_max"]) == (0.0, 0.0, 0.26, 0.56)
    assert len(system.connections) == 3 + 12 * 3  # 12 per drive: docs/interfaces.md, the connector convention


@pytest.fixture(scope="module")
def rps_system(tmp_path_factory):
    """MAST_3RPS.ssp built with its FMUs (the Python ones)."""
    return build_mechanism_system("3RPS", tmp_path_factory.mktemp("rps"))


def test_the_3rps_fmus_have_the_description_s_parameters(rps_system):
    from mast.core.components import fmu_parameters

    fmus = rps_system.parent.parent / "fmus"
    mech = fmu_parameters(fmus / "Mast3RPS.fmu")
    assert list(mech) == ["kinematics", *RPS.parameters, "attached", "T_mech"]
    assert mech["kinematics"] == "3RPS" and mech["R_b"] == RPS.parameters["R_b"].value
    ctrl = fmu_parameters(fmus / "Mast3RPSController.fmu")
    assert set(RPS.kinematic) <= set(ctrl) and "H" not in ctrl and ctrl["kinematics"] == "3RPS"


def kinetic(mech, pose, rho_dot) -> float:
    """Kinetic energy [J] of the oracle's 3-RPS at ``pose`` with joint rates ``rho_dot``: its own kinematics (the
    platform's twist from newton_euler, each leg turning about its base joint, the carriage at S)."""
    import newton_euler as ne
    import numpy as np

    (vP, w), _ = np.split(ne.platform_motion(mech, pose, rho_dot, np.zeros(3))[0], 2), None
    R = ne.rotation(*pose[3:])
    T = 0.0
    for body in mech.platform:
        c = R @ np.asarray(body.com)
        v = vP + np.cross(w, c)
        T += 0.5 * body.mass * v @ v + 0.5 * w @ (R @ np.asarray(body.tensor) @ R.T) @ w
    for leg, S, rd in zip(mech.legs, ne.points(mech, pose), rho_dot):
        d = S - np.asarray(leg.base)
        ln = np.linalg.norm(d)
        u = d / ln
        vS = vP + np.cross(w, S - np.asarray(pose[:3]))
        wl = np.cross(u, (vS - rd * u) / ln)  # the leg turns about its base joint's axis
        Rl = np.column_stack((u, leg.t / np.linalg.norm(leg.t), np.cross(u, leg.t / np.linalg.norm(leg.t))))
        cylinder, rod = leg.bodies
        vc = np.cross(wl, Rl @ np.asarray(cylinder.com))
        for body, v in ((cylinder, vc), (rod, vS)):
            T += 0.5 * body.mass * v @ v + 0.5 * wl @ (Rl @ np.asarray(body.tensor) @ Rl.T) @ wl
    return T


@pytest.mark.parametrize("axis, amplitude", [("z", 0.01), ("theta", math.radians(3.0))])
def test_a_3rps_run_against_the_newton_euler_oracle(rps_system, axis, amplitude):
    """The system run (Python FMUs, 2 Hz sine): the pose and forces the mechanism reports for every recorded state
    (every 100 us) against the oracle's kinematics and inverse dynamics (the mechanism's outputs at t + h: its full
    update, pose, M and b, of the actuators' positions and velocities at the last instant t0 + k T_mech, with the
    accelerations at t, F = M rho_ddot(t) + b); at the start, at rest, the statics."""
    import newton_euler as ne
    import numpy as np
    from test_rps import oracle_3rps

    from mast.core.motion import SineMotion
    from mast.core.run import simulate

    mech = oracle_3rps()
    res = simulate(rps_system, SineMotion(axis=axis, amplitude=amplitude, frequency=2.0), 0.5, record_step=1e-4)
    rho = np.column_stack([res[f"actuator_{k}.rho"] for k in (1, 2, 3)])
    rd = np.column_stack([res[f"actuator_{k}.rho_dot"] for k in (1, 2, 3)])
    rdd = np.column_stack([res[f"actuator_{k}.rho_ddot"] for k in (1, 2, 3)])
    F = np.column_stack([res[f"mechanism.F_{k}"] for k in (1, 2, 3)])
    q = np.column_stack([res[f"mechanism.{c}"] for c in ("z", "psi", "theta")])
    assert np.ptp(q[:, ("z", "psi", "theta").index(axis)]) > 0.5 * amplitude
    ticks = np.rint(res.time / 1e-4).astype(int)
    worst, every = 0.0, round(1e-3 / 1e-4)  # T_mech = 1 ms (attached.ssv)
    for k in range(0, len(res.time) - 1, 7):  # state k -> the outputs at k + 1; 7: every phase of an update period
        u = k - ticks[k] % every  # the last full update: its pose held, M and b of its positions and velocities
        pose = ne.full_pose(mech, q[k + 1])
        np.testing.assert_allclose(ne.joints(mech, pose), rho[u], rtol=0.0, atol=1e-10)
        expected = ne.forces(mech, pose, rd[u], rdd[k])
        worst = max(worst, float(np.max(np.abs(F[k + 1] - expected)) / np.max(np.abs(expected))))
    assert worst < 1e-9
    # at rest (t = 0: the actuators at rho_0, still): the weight, as the oracle's statics carry it
    assert np.all(rd[0] == 0.0)
    rest = ne.forces(mech, ne.full_pose(mech, q[0]), np.zeros(3), rdd[0])
    np.testing.assert_allclose(F[1], rest, rtol=1e-9)


def test_the_3rps_block_s_power_balance_along_smooth_motions():
    """The mechanism block of the 3-RPS FMU (its class from the FMU's parameters) driven along smooth joint motions:
    the power its forces deliver, sum F_k rho_dot_k, is d/dt (T + V) of the oracle's bodies (T from its own
    kinematics, V from the centres of mass), by central differences in time (as the 3PRS's
    test_mechanism_dynamics.py::test_power_balance_along_random_trajectories)."""
    import newton_euler as ne
    import numpy as np
    from test_rps import oracle_3rps, potential

    mech = oracle_3rps()
    block = MechanismBlock.for_parameters(rps_parameters())(rps_parameters(), "rps")
    home = np.asarray(RPS.describe().topology.home)
    rng = np.random.default_rng(5)
    for _ in range(3):
        A, w, p = rng.uniform(-1, 1, 3) * (0.03, 0.15, 0.15), rng.uniform(3.0, 12.0, 3), rng.uniform(0, 6.3, 3)

        def pose_at(t):
            return ne.full_pose(mech, home + A * np.sin(w * t + p))

        def joints(t, h=1e-5):
            rho = ne.joints(mech, pose_at(t))
            up, down = ne.joints(mech, pose_at(t + h)), ne.joints(mech, pose_at(t - h))
            h2 = 1e-3
            up2, down2 = ne.joints(mech, pose_at(t + h2)), ne.joints(mech, pose_at(t - h2))
            return rho, (up - down) / (2 * h), (up2 - 2 * rho + down2) / (h2 * h2)

        def energy(t):
            rho, rd, _ = joints(t)
            return kinetic(mech, pose_at(t), rd) + potential(mech, home + A * np.sin(w * t + p))

        powers, rates = [], []
        block.set(**{f"rho_{k + 1}": v for k, v in enumerate(joints(0.05)[0])})
        block.initialize(0.0)
        for t in np.linspace(0.05, 0.6, 8):
            rho, rd, rdd = joints(t)
            block.set(
                **{
                    f"{n}_{k + 1}": v[k]
                    for n, v in (("rho", rho), ("rho_dot", rd), ("rho_ddot", rdd))
                    for k in range(3)
                }
            )
            block.do_step(t, 1e-3)
            powers.append(np.array([block.get(f"F_{k}") for k in (1, 2, 3)]) @ rd)
            rates.append((energy(t + 1e-4) - energy(t - 1e-4)) / 2e-4)
        scale = np.max(np.abs(powers))
        assert scale > 1.0  # watts flow: a real balance
        np.testing.assert_allclose(powers, rates, atol=2e-5 * scale)


def test_compare_swaps_the_3rps_fmu_into_its_own_system(rps_system, tmp_path):
    """`mast compare --mechanism .../Mast3RPS.fmu`: the FMU goes into ssp/MAST_3RPS.ssd (its controller and actuators
    are the 3-RPS's), its controller bound to the FMU's geometry (R_b, r, alpha_k, not the 3PRS's names)."""
    from fmus.mechanism.designs import kinematic_names
    from mast.analyses.compare import own_system, prepare
    from mast.core.components import fmu_parameters
    from mast.core.designs import design
    from mast.core.ssp import SSPArchive

    fmus = rps_system.parent.parent / "fmus"
    params = fmu_parameters(fmus / "Mast3RPS.fmu")
    assert own_system(fmus / "Mast3RPS.fmu", params) == design("3RPS").ssd
    assert own_system(fmus / "MastActuator.fmu", {"kinematics": "3PRS"}) is None
    assert kinematic_names(params) == ("kinematics", *RPS.kinematic)
    assert kinematic_names({"kinematics": "3PRS"}) == designs.KINEMATIC_PARAMETERS_NAMES
    (candidate,) = prepare([fmus / "Mast3RPS.fmu"], tmp_path, fmu_dir=fmus)
    with SSPArchive(candidate.ssp) as archive:
        comps = archive.system.components
        assert comps["controller"].parameters["R_b"] == RPS.parameters["R_b"].value
        assert comps["actuator_2"].parameters["M_load"] == 0.0 and comps["actuator_2"].parameters["rho_0"] > 0.4


def test_every_design_s_mechanism_and_controller_have_a_native_form():
    """The mechanisms of every description and their controllers (on the native mechanism's cold start, lengths and
    checks: mast_controller.c, mast_mechanism.c): their systems' native SSPs are native throughout
    (tests/test_native_mechanisms.py). The EMPS bench's models have none (the generator knows no such block)."""
    from mast.core.native.build import has_native_form

    names = ("3RPS", "6UPS", "6PUS")
    assert all(has_native_form(f"Mast{name}") and has_native_form(f"Mast{name}Controller") for name in names)
    assert not has_native_form("MastEmpsController")
