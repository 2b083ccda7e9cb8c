"""The controllers for n axes (fmus/controller/, issue "Describe a parallel mechanism in one file"), shown on
mechanisms other than the 3PRS, written here as scratch descriptions for the engine:

- a planar two-leg table (n = 2, coordinates x and z: two legs of variable length from base points
  (-d, 0, 0) and (d, 0, 0) to one platform point), whose inverse and direct kinematics and Jacobian are
  written out by hand below;
- a 6-UPS hexapod (n = 6, all six pose components, legs from a base hexagon to a platform hexagon).

The state layout for n = 1..8 (no two fields overlap; n = 3 is the 3PRS's layout of before); the joint cascade's
tick of n axes against the P/PI cascade written out here; the workspace law against the pose-space P law by hand;
the model-based laws per axis against the 3PRS's axes; the interface by the connector convention; and the
refusals (a rotary drive, a controller class of other axes, a mode command of the wrong length); the inverse
model's mechanism forces for n = 2 against the statics of the 2-leg table.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fmus.common import tracer as E
from fmus.common.parameters import ParameterError
from fmus.controller.computed_torque import ComputedTorqueController
from fmus.controller.feedforward import FeedForwardController
from fmus.controller.inverse_model import InverseModel
from fmus.controller.model import ControllerBlock
from fmus.controller.tick import LAYOUT, SIZE, layout, size
from fmus.controller.workspace import WorkspaceController
from fmus.mechanism.designs import TRACED_PARAMETERS, describe
from fmus.mechanism.engine import Body, Description, Engine, Evaluation
from fmus.mechanism.kinematics import KinematicsError
from fmus.mechanism.topology import Coordinate, Drive, Topology, TopologyError
from mast.core.build import default_parameters

IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
PLATFORM = Body("platform", 2.0, (0.0, 0.0, 0.0), ((0.01, 0.0, 0.0), (0.0, 0.01, 0.0), (0.0, 0.0, 0.01)))


# ---------------------------------------------------------------------------- scratch mechanisms
class TwoLegs(Description):
    """Planar table: platform point P = (x, 0, z), legs rho_i = |P - A_i|, A_1 = (-d, 0, 0), A_2 = (d, 0, 0)."""

    name = "2-leg table"
    coordinates = ("x", "z")
    joints = ("rho_1", "rho_2")
    bodies = (PLATFORM,)

    def __init__(self, d: float = 0.3, kind: str = "linear") -> None:
        self.d, self.kind = d, kind

    def evaluate(self, q):
        x, z = q
        d = self.d
        return Evaluation(
            [E.sqrt((x + d) * (x + d) + z * z), E.sqrt((x - d) * (x - d) + z * z)],
            [x, 0.0, z, 0.0, 0.0, 0.0],
            [((x, 0.0, z), IDENTITY)],
        )

    def guess(self, rho):
        return (0.0, 0.4)

    def key(self):
        return (type(self).__name__, self.d, self.kind)

    @property
    def topology(self) -> Topology:
        return Topology(
            self.name,
            (Coordinate("x"), Coordinate("z")),
            tuple(Drive(j, self.kind, (0.2, 0.8)) for j in self.joints),
            (0.0, 0.4),
        )


def rzyx(psi, theta, phi):
    cx, sx, cy, sy, cz, sz = (E.cos(psi), E.sin(psi), E.cos(theta), E.sin(theta), E.cos(phi), E.sin(phi))
    return (
        (cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx),
        (sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx),
        (-sy, cy * sx, cy * cx),
    )


def hexagon(radius: float, offset: float) -> list[tuple[float, float, float]]:
    angles = [k * 2.0 * math.pi / 3.0 + s * offset for k in range(3) for s in (-1.0, 1.0)]
    return [(radius * math.cos(a), radius * math.sin(a), 0.0) for a in sorted(angles)]


class Hexapod(Description):
    """6-UPS: legs rho_i = |p + R b_i - a_i| between a base and a platform hexagon, q = the six pose values."""

    name = "6-UPS"
    coordinates = ("x", "y", "z", "psi", "theta", "phi")
    joints = tuple(f"rho_{i}" for i in range(1, 7))
    bodies = (PLATFORM,)
    lengths = (1.0, 1.0, 1.0, 0.2, 0.2, 0.2)
    base, top = hexagon(0.35, 0.25), hexagon(0.2, 0.8)

    def evaluate(self, q):
        x, y, z, psi, theta, phi = q
        R = rzyx(psi, theta, phi)
        legs = []
        for a, b in zip(self.base, self.top):
            v = [(x, y, z)[i] + sum(R[i][k] * b[k] for k in range(3)) - a[i] for i in range(3)]
            legs.append(E.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]))
        E.require(self.within_stroke, *legs)
        return Evaluation(legs, list(q), [((x, y, z), R)])

    @staticmethod
    def within_stroke(*legs) -> None:
        if not max(legs) < 0.7:
            raise KinematicsError(f"a leg of {max(legs):.3g} m is beyond its stroke (0.7 m)")

    def guess(self, rho):
        return (0.0, 0.0, 0.45, 0.0, 0.0, 0.0)

    def key(self):
        return (type(self).__name__,)

    @property
    def topology(self) -> Topology:
        return Topology(
            self.name,
            tuple(Coordinate(c) for c in self.coordinates),
            tuple(Drive(j, "linear", (0.3, 0.7)) for j in self.joints),
            self.guess(()),
        )


@pytest.fixture(scope="module")
def params() -> dict:
    """The joint cascade's parameters of the default system (the 3PRS's geometry set is validated, but the scratch
    mechanisms' engines are the controllers' kinematic model)."""
    return default_parameters("MastController")


def two_leg_ik(x: float, z: float, d: float = 0.3) -> tuple[float, float]:
    return (math.hypot(x + d, z), math.hypot(x - d, z))


def two_leg_dk(r1: float, r2: float, d: float = 0.3) -> tuple[float, float]:
    """The circles' intersection above the base: r1^2 - r2^2 = 4 d x."""
    x = (r1 * r1 - r2 * r2) / (4.0 * d)
    return x, math.sqrt(r1 * r1 - (x + d) ** 2)


def two_leg_jinv(x: float, z: float, d: float = 0.3) -> np.ndarray:
    """drho/dq: rows the legs, columns (x, z)."""
    r1, r2 = two_leg_ik(x, z, d)
    return np.array([[(x + d) / r1, z / r1], [(x - d) / r2, z / r2]])


# ---------------------------------------------------------------------------- the layout
#: what each field of the state holds, as a number of doubles for n axes and p traced parameters
FIELDS = {
    "n": lambda n: 1,
    "t0": lambda n: 1,
    "ik": lambda n: 1,
    "pose": lambda n: n,
    "x_v": lambda n: n,
    "rho_cmd": lambda n: n,
    "omega_cmd": lambda n: n,
    "i_cmd": lambda n: n,
    "failed": lambda n: 1,
    "gains": lambda n: 4,
    "mode": lambda n: 1,
    "hist": lambda n: 4 * n,
    "k": lambda n: 1,
    "i_ff": lambda n: n,
    "warm": lambda n: 1,
    "guess": lambda n: n,
    "model_args": lambda n: 3 * n,
    "rates": lambda n: 2 * n,
    "own": lambda n: max(2, n),
    "N_pos": lambda n: 1,
    "N_vel": lambda n: 1,
    "T_cur": lambda n: 1,
    "T_pos": lambda n: 1,
    "i_R": lambda n: 1,
    "cb": lambda n: 1,
    "sb": lambda n: 1,
    "attached": lambda n: 1,
    "P": lambda n: len(TRACED_PARAMETERS),
    "model": lambda n: 9,
    "lengths": lambda n: n,
}


@pytest.mark.parametrize("n", range(1, 9))
def test_the_state_layout_for_n_axes_gives_every_field_its_own_doubles(n):
    L = layout(n, len(TRACED_PARAMETERS))
    assert set(L) - {"size"} == set(FIELDS)
    spans = sorted((L[name], L[name] + length(n), name) for name, length in FIELDS.items())
    for (a0, a1, first), (b0, b1, second) in zip(spans, spans[1:]):
        assert a1 <= b0, f"n = {n}: {first} [{a0}, {a1}) overlaps {second} [{b0}, {b1})"
    assert spans[0][0] == 0 and spans[-1][1] == L["size"] == size(n, len(TRACED_PARAMETERS))
    # the commands are one block (the tick stores and outputs them at once), in the order of the outputs
    assert L["omega_cmd"] == L["rho_cmd"] + n and L["i_cmd"] == L["rho_cmd"] + 2 * n


def test_the_layout_for_three_axes_is_the_3prs_layout_of_before():
    before = {
        "n": 0,
        "t0": 1,
        "ik": 2,
        "pose": 3,
        "x_v": 6,
        "rho_cmd": 15,
        "omega_cmd": 18,
        "i_cmd": 21,
        "failed": 24,
        "gains": 25,
        "mode": 29,
        "hist": 32,
        "k": 44,
        "i_ff": 45,
        "warm": 48,
        "guess": 49,
        "model_args": 52,
        "rates": 61,
        "own": 67,
        "N_pos": 70,
        "N_vel": 71,
        "T_cur": 72,
        "T_pos": 73,
        "i_R": 74,
        "cb": 75,
        "sb": 76,
        "attached": 77,
        "P": 78,
        "model": 102,
    }
    assert {k: LAYOUT[k] for k in before} == before
    assert SIZE == 114 and LAYOUT["lengths"] == SIZE - 3
    assert ControllerBlock.LAYOUT == LAYOUT and ControllerBlock.SIZE == SIZE
    with pytest.raises(ValueError, match="n = 0"):
        layout(0, 24)


# ---------------------------------------------------------------------------- the interface
def test_a_controller_for_another_mechanism_declares_its_axes_by_the_connector_convention(params):
    hexapod = ControllerBlock.for_topology(Hexapod().topology)
    pose = ("x", "y", "z", "psi", "theta", "phi")
    assert hexapod.INPUTS == (
        *(f"{c}_cmd" for c in pose),
        *(f"rho_{k}" for k in range(1, 7)),
        *(f"omega_m_{k}" for k in range(1, 7)),
    )
    assert hexapod.OUTPUTS == (
        *(f"rho_cmd_{k}" for k in range(1, 7)),
        *(f"omega_cmd_{k}" for k in range(1, 7)),
        *(f"i_cmd_{k}" for k in range(1, 7)),
    )
    assert [hexapod.UNITS[f"{c}_cmd"] for c in pose] == ["m", "m", "m", "rad", "rad", "rad"]
    assert hexapod.UNITS["rho_6"] == "m" and hexapod.UNITS["omega_m_6"] == "rad/s" and hexapod.UNITS["i_cmd_6"] == "A"
    assert hexapod.FEEDTHROUGH == {}  # the commands change in do_step only (FMI 2.0's calling sequence)
    assert hexapod.SIZE == size(6, len(TRACED_PARAMETERS)) and issubclass(hexapod, ControllerBlock)
    # made once; the 3PRS's is the class itself; each controller keeps its own declarations
    assert ControllerBlock.for_topology(Hexapod().topology) is hexapod
    assert ControllerBlock.for_topology(describe(params, masses=False).topology) is ControllerBlock
    workspace = WorkspaceController.for_topology(TwoLegs().topology)
    assert [p.name for p in workspace.PARAMETERS][-2:] == ["k_v_scale_x", "k_v_scale_z"]
    assert "k_v_scale_theta" not in {p.name for p in workspace.PARAMETERS}
    assert "inverse Jacobian" in workspace.DESCRIPTIONS["omega_cmd_2"]
    assert ComputedTorqueController.for_topology(TwoLegs().topology).MODES == ("pose", "joint", "current")


# ---------------------------------------------------------------------------- the joint cascade
def cascade_by_hand(P: dict, inputs: list[tuple], d: float = 0.3) -> list[tuple]:
    """The P/PI cascade of n = 2 axes written out (model.py's docstring), one tick per row of ``inputs``
    (x_cmd, z_cmd, rho_1, rho_2, omega_m_1, omega_m_2): (rho_cmd, omega_cmd, i_cmd) after each tick."""
    i_R = P["p"] / (2.0 * math.pi * P["i_r"])
    N_pos, N_vel = round(P["T_pos"] / P["T_cur"]), round(P["T_vel"] / P["T_cur"])
    rho_cmd, omega_cmd, i_cmd, x = [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]
    out = []
    for n, (xc, zc, r1, r2, w1, w2) in enumerate(inputs):
        if n % N_pos == 0:
            rho_cmd = list(two_leg_ik(xc, zc, d))
            omega_cmd = [P["k_v"] * (rc - r) / i_R for rc, r in zip(rho_cmd, (r1, r2))]
        if n % N_vel == 0:
            for j, w in enumerate((w1, w2)):
                e = omega_cmd[j] - w
                v = P["k_p"] * e + x[j]
                if abs(v) <= P["i_max"] or (v > 0.0) != (e > 0.0):  # integrate unless winding up further
                    x[j] += P["k_i"] * P["T_vel"] * e
                i_cmd[j] = max(-P["i_max"], min(P["i_max"], v))
        out.append((tuple(rho_cmd), tuple(omega_cmd), tuple(i_cmd)))
    return out


def test_the_joint_cascade_of_two_axes_is_the_p_pi_cascade_written_out(params):
    P = {**params, "i_max": 2.0}
    cls = ControllerBlock.for_topology(TwoLegs().topology)
    block = cls(P, "two_legs", kinematics=Engine(TwoLegs(), g=0.0))
    rng = np.random.default_rng(11)
    ticks = 40
    poses = [(0.02 * math.sin(0.3 * k), 0.4 + 0.01 * math.cos(0.2 * k)) for k in range(ticks)]
    inputs = [
        (*q, *(r + 1e-3 * rng.standard_normal() for r in two_leg_ik(*q)), *(20.0 * rng.standard_normal(2)))
        for q in poses
    ]
    expected = cascade_by_hand(P, inputs)
    block.set(**dict(zip(cls.INPUTS, inputs[0])))
    block.initialize(0.0)
    saturated = 0
    T = P["T_cur"]
    for k, row in enumerate(inputs):
        block.set(**dict(zip(cls.INPUTS, row)))
        block.do_step(k * T, T)
        out = block.outputs()
        rho_cmd, omega_cmd, i_cmd = expected[k]
        np.testing.assert_allclose([out["rho_cmd_1"], out["rho_cmd_2"]], rho_cmd, rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose([out["omega_cmd_1"], out["omega_cmd_2"]], omega_cmd, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose([out["i_cmd_1"], out["i_cmd_2"]], i_cmd, rtol=1e-12, atol=1e-12)
        saturated += sum(abs(i) == P["i_max"] for i in i_cmd)
    assert 0 < saturated < 2 * ticks  # the limit and the anti-windup were exercised, and the linear range too
    assert block.ticks_per_position > 1  # and ticks without a position law


def test_the_hexapod_controller_tracks_its_legs_through_its_own_kinematics(params):
    cls = ControllerBlock.for_topology(Hexapod().topology)
    block = cls(params, "hexapod", kinematics=Engine(Hexapod(), g=0.0))
    q = (0.01, -0.02, 0.46, 0.03, -0.02, 0.05)
    block.set(**dict(zip(cls.INPUTS[:6], q)), **{f"rho_{k}": 0.5 for k in range(1, 7)})
    block.initialize(0.0)
    block.do_step(0.0, params["T_cur"])
    out = block.outputs()
    # each leg's length, from the poses' points directly (not the engine)
    desc = Hexapod()
    R = np.array(rzyx(*q[3:]), dtype=float)
    legs = [np.linalg.norm(np.array(q[:3]) + R @ np.array(b) - np.array(a)) for a, b in zip(desc.base, desc.top)]
    np.testing.assert_allclose([out[f"rho_cmd_{k}"] for k in range(1, 7)], legs, rtol=1e-14)
    i_R = params["p"] / (2.0 * math.pi * params["i_r"])
    np.testing.assert_allclose(
        [out[f"omega_cmd_{k}"] for k in range(1, 7)], [params["k_v"] * (r - 0.5) / i_R for r in legs], rtol=1e-12
    )
    with pytest.raises(ValueError, match="needs six rho_cmd values"):
        block.set_mode("joint", (0.5,) * 3)
    block.set(z_cmd=9.0)
    message = r"pose command x = 0.01 m, y = -0.02 m, z = 9.0 m, psi = 0.03 rad, .* beyond its stroke"
    with pytest.raises(KinematicsError, match=message):
        block.do_step(params["T_cur"], params["T_cur"] * block.ticks_per_position)


# ---------------------------------------------------------------------------- the workspace law
def test_the_workspace_law_of_two_axes_is_the_pose_space_p_law_written_out(params):
    P = {**params, "k_v_scale_x": 2.5, "k_v_scale_z": 0.6}
    cls = WorkspaceController.for_topology(TwoLegs().topology)
    block = cls(P, "two_legs", kinematics=Engine(TwoLegs(), g=0.0))
    rho = (0.52, 0.47)
    q_cmd = (0.01, 0.41)
    block.set(x_cmd=q_cmd[0], z_cmd=q_cmd[1], rho_1=rho[0], rho_2=rho[1])
    block.initialize(0.0)
    block.do_step(0.0, P["T_cur"])
    q = two_leg_dk(*rho)
    K = np.diag([P["k_v"] * 2.5, P["k_v"] * 0.6])
    i_R = P["p"] / (2.0 * math.pi * P["i_r"])
    omega = two_leg_jinv(*q) @ K @ (np.array(q_cmd) - np.array(q)) / i_R
    out = block.outputs()
    np.testing.assert_allclose([out["omega_cmd_1"], out["omega_cmd_2"]], omega, rtol=1e-9)
    assert block.K == (P["k_v"] * 2.5, P["k_v"] * 0.6)


# ---------------------------------------------------------------------------- the model-based laws
@pytest.mark.parametrize(
    "kind, ident",
    [(ComputedTorqueController, "MastComputedTorqueController"), (FeedForwardController, "MastFeedForwardController")],
)
def test_the_model_based_laws_of_two_axes_are_the_3prs_laws_axis_by_axis(kind, ident):
    """With the actuators alone (attached = 0) each axis' law is the same whatever the others: two axes of a 2-leg
    table fed what axes 1 and 3 of the 3PRS's controller are fed (joint mode) command the same currents."""
    P = {**default_parameters(ident), "attached": 0}
    three = kind(P, "three")
    two_cls = kind.for_topology(TwoLegs().topology)
    two = two_cls(P, "two", kinematics=Engine(TwoLegs(), g=0.0))
    assert two.model.n == 2
    rng = np.random.default_rng(3)
    T = P["T_cur"]
    three.set_mode("joint", (0.15, 0.15, 0.15))
    two.set_mode("joint", (0.15, 0.15))
    three.initialize(0.0)
    two.initialize(0.0)
    compared = 0
    for k in range(30):
        cmd = 0.15 + 2e-3 * np.sin(0.2 * k + np.array([0.0, 1.0, 2.0]))
        meas = 0.15 + 1e-4 * rng.standard_normal(3)
        speed = 5.0 * rng.standard_normal(3)
        three.set_mode("joint", tuple(cmd))
        two.set_mode("joint", (cmd[0], cmd[2]))
        three.set(**{f"rho_{j + 1}": meas[j] for j in range(3)}, **{f"omega_m_{j + 1}": speed[j] for j in range(3)})
        two.set(rho_1=meas[0], rho_2=meas[2], omega_m_1=speed[0], omega_m_2=speed[2])
        three.do_step(k * T, T)
        two.do_step(k * T, T)
        a, b = three.outputs(), two.outputs()
        for mine, theirs in ((1, 1), (2, 3)):
            for name in ("rho_cmd", "omega_cmd", "i_cmd"):
                assert b[f"{name}_{mine}"] == a[f"{name}_{theirs}"], (k, name)
        compared += a["i_cmd_1"] != 0.0
    assert compared > 10


def test_what_a_law_cannot_do_for_n_axes_is_refused_naming_why(params):
    rotary = TwoLegs(kind="rotary")
    with pytest.raises(TopologyError, match=r"rho_1, rho_2 are rotary.*i_R = p / \(2 pi i_r\)"):
        ControllerBlock.for_topology(rotary.topology)
    with pytest.raises(TopologyError, match="rotary"):
        ControllerBlock.for_topology(TwoLegs().topology)(params, "x", kinematics=Engine(rotary, g=0.0))
    # a class of other axes than its kinematic model's
    with pytest.raises(ParameterError, match=r"2-leg table with coordinates x, z \(two drives\).*for_topology"):
        ControllerBlock(params, "x", kinematics=Engine(TwoLegs(), g=0.0))


def test_the_inverse_model_carries_the_weight_of_a_two_leg_table():
    """attached = 1, n = 2, at rest at x = 0, z = 0.4 m (legs 0.5 m long, A_i = (-+0.3, 0, 0)): by symmetry each
    leg pushes f along itself with 2 f z / rho = m g (statics), so each motor's torque exceeds the actuators-alone
    torque by i_R f = i_R m g rho / (2 z)."""
    P = {**default_parameters("MastComputedTorqueController"), "attached": 1}
    loaded = InverseModel(P, "x", dynamics=Engine(TwoLegs(), g=9.81))
    alone = InverseModel({**P, "attached": 0}, "x", n=2)
    rho = (0.5, 0.5)
    f = PLATFORM.mass * 9.81 * 0.5 / (2.0 * 0.4)
    extra = [
        a - b for a, b in zip(loaded.torques(rho, (0.0, 0.0), (0.0, 0.0)), alone.torques(rho, (0.0, 0.0), (0.0, 0.0)))
    ]
    assert extra == pytest.approx([loaded.i_R * f] * 2, rel=1e-12)


def test_a_controller_fmu_takes_the_axes_of_its_parameters(params, monkeypatch):
    """Block.for_parameters (what an FMU calls with its built-in parameters): the 3PRS's set gives the class
    itself, a set describing the 2-leg table the class with its axes (x_cmd, z_cmd; two drives)."""
    from fmus.mechanism import designs

    assert ControllerBlock.for_parameters(params) is ControllerBlock
    monkeypatch.setitem(designs.KINEMATICS, "2-leg", lambda p, masses=True: TwoLegs())
    two = ControllerBlock.for_parameters({**params, "kinematics": "2-leg"})
    assert two is ControllerBlock.for_topology(TwoLegs().topology)
    assert [v for v in two.INPUTS if v.endswith("_cmd")] == ["x_cmd", "z_cmd"]
    assert [v for v in two.OUTPUTS if v.startswith("i_cmd")] == ["i_cmd_1", "i_cmd_2"]
