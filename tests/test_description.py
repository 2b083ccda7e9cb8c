"""Mechanism description files (fmus/mechanism/description.py, legs.py; docs/mechanism.md).

- the shipped 3PRS designs: their files give the parameter sets the SSP binds, and the description
  traced with its parameters as inputs computes the same floats as with them as constants;
- every leg template against kinematics written here from the template's definition (numpy, no
  engine code): the 6-UPS and 6-PUS leg lengths and slider positions, the 3-RPS leg lengths with the
  parasitic motion from S_i . t_i = 0 solved by Newton here; DK round trips on each;
- bad files: each refused with the file, the leg or body, and what was expected.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from fmus.common.parameters import ParameterError
from fmus.mechanism.description import DESCRIPTIONS, DescriptionError, Expression, load
from fmus.mechanism.engine import Engine

BASE = (DESCRIPTIONS / "3PRS_T.toml").read_text(encoding="utf-8")


def rot(psi, theta, phi):
    cx, sx, cy, sy, cz, sz = (
        math.cos(psi),
        math.sin(psi),
        math.cos(theta),
        math.sin(theta),
        math.cos(phi),
        math.sin(phi),
    )
    return (
        np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
        @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    )


def written(tmp_path: Path, text: str, name: str = "bad.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def changed(old: str, new: str, text: str = BASE) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


# ---- the shipped designs ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "name, geometry",
    [("3PRS_T", "geometry_3prs"), ("3PRS_120", "geometry_3prs_120"), ("3PRS_inclined", "geometry_3prs_inclined")],
)
def test_each_design_file_holds_the_values_its_parameter_sets_bind(name, geometry):
    from mast.core.build import SSP_SRC
    from mast.core.ssv import parse_ssv

    file = load(name)
    bound = {
        k: p.value
        for set_ in ("mass_3prs", geometry)
        for k, p in parse_ssv(SSP_SRC / "resources" / f"{set_}.ssv").items()
    }
    values = file.values()
    assert bound["kinematics"] == file.name == "3PRS"
    assert {k: float(bound[k]) for k in values} == values
    for p in file.parameters.values():
        assert p.source.strip() and p.unit


def test_every_parameter_has_a_unit_and_a_source_and_the_traced_ones_are_inputs():
    file = load("3PRS_T")
    assert file.traced[:7] == ("H", "r", "L", "alpha_1", "alpha_2", "alpha_3", "beta")
    assert file.kinematic == file.traced[:7]
    params = {**file.values(), "m_payload": 1.2, "payload_z": 0.05, "I_payload_zz": 0.01, "beta": 0.1, "H": 0.45}
    const = Engine(file.describe(params), g=params["g"])
    traced = Engine(file.describe(params, traced=True), g=params["g"])
    assert traced.parameters == file.traced and const.parameters == ()
    q, rd, rdd = (0.38, 0.04, -0.05), (0.01, -0.02, 0.03), (0.3, -0.1, 0.2)
    _, J, _ = const.jacobian(q)
    a, b = np.array(const.forces(q, J, rd, rdd)), np.array(traced.forces(q, J, rd, rdd))
    np.testing.assert_allclose(b, a, rtol=1e-14, atol=1e-15)
    assert const.ik(q) == traced.ik(q)


# ---- the templates against this file's own kinematics --------------------------------------------------
HEXAPOD = """
[mechanism]
name = "6UPS"
coordinates = ["x", "y", "z", "psi", "theta", "phi"]
gravity = "g"
home = { x = 0.0, y = 0.0, z = "h0", psi = 0.0, theta = 0.0, phi = 0.0 }

[parameters]
Rb = { value = 0.5, unit = "m", source = "assumed: a test hexapod" }
Rp = { value = 0.3, unit = "m", source = "assumed: a test hexapod" }
h0 = { value = 0.6, unit = "m", source = "assumed: a test hexapod" }
gap = { value = 12.0, unit = "deg", source = "assumed: half the angle between a pair of joints" }
m_p = { value = 5.0, unit = "kg", source = "assumed" }
m_c = { value = 0.8, unit = "kg", source = "assumed" }
g = { value = 9.81, unit = "m/s2", source = "standard gravity" }

[leg]
template = "UPS"
drive = { joint = "P", kind = "linear", stroke = [0.4, 1.0] }
bodies.cylinder = { mass = "m_c", com = [0.15, 0.0, 0.0], inertia = [[0.001, 0, 0], [0, 0.01, 0], [0, 0, 0.01]] }
bodies.rod = { mass = "0.5 * m_c", com = [-0.1, 0.0, 0.0] }

[[bodies]]
name = "platform"
mass = "m_p"
inertia = [[0.2, 0, 0], [0, 0.2, 0], [0, 0, 0.35]]
"""


def hexapod_legs(template: str) -> str:
    legs = []
    for k in range(6):
        pair = 120 * (k // 2)
        b = f"radians({pair} + {'-' if k % 2 == 0 else ''}gap)"
        p = f"radians({pair + 60 * (1 if k % 2 else -1)} + {'' if k % 2 else '-'}gap)"
        leg = [
            f'name = "leg_{k + 1}"',
            f'base = ["Rb * cos({b})", "Rb * sin({b})", 0.0]',
            f'platform = ["Rp * cos({p})", "Rp * sin({p})", 0.0]',
            f'axis = ["-sin({b})", "cos({b})", 0.0]',
        ]
        if template == "PUS":
            leg = [
                f'name = "leg_{k + 1}"',
                f'base = ["Rb * cos({b})", "Rb * sin({b})", 0.0]',
                "guide = [0.0, 0.0, 1.0]",
                'length = "Lp"',
                f'platform = ["Rp * cos({p})", "Rp * sin({p})", 0.0]',
                f'axis = ["-sin({b})", "cos({b})", 0.0]',
            ]
        legs.append("[[legs]]\n" + "\n".join(leg) + "\n")
    return "\n".join(legs)


def points(file, values):
    """(b_i, s_i) from the parameters, written here: the test hexapod's layout."""
    Rb, Rp, gap = values["Rb"], values["Rp"], math.radians(values["gap"])
    out = []
    for k in range(6):
        pair = math.radians(120 * (k // 2))
        b = pair + (gap if k % 2 else -gap)
        p = pair + math.radians(60 * (1 if k % 2 else -1)) + (gap if k % 2 else -gap)
        out.append(
            (np.array([Rb * math.cos(b), Rb * math.sin(b), 0.0]), np.array([Rp * math.cos(p), Rp * math.sin(p), 0.0]))
        )
    return out


def test_a_6ups_hexapod_from_a_file_gives_the_leg_lengths_and_its_dk_the_pose(tmp_path):
    file = load(written(tmp_path, HEXAPOD + hexapod_legs("UPS"), "hexapod.toml"))
    desc = file.describe()
    assert desc.topology.n == 6 and desc.topology.parasitic == () and desc.topology.home[2] == 0.6
    eng = Engine(desc, g=9.81)
    rng = np.random.default_rng(4)
    for _ in range(10):
        q = np.array([0.0, 0.0, 0.6, 0.0, 0.0, 0.0]) + rng.uniform(-1, 1, 6) * [0.05, 0.05, 0.05, 0.1, 0.1, 0.1]
        R = rot(*q[3:])
        own = [np.linalg.norm(q[:3] + R @ s - b) for b, s in points(file, file.values())]
        np.testing.assert_allclose(eng.ik(q), own, rtol=1e-14)
        back = eng.dk(own, desc.topology.home)[0]
        np.testing.assert_allclose(back, q, atol=1e-11)
    # power balance with the leg bodies' masses: t_rho . rho_dot = dT/dt + dV/dt by finite differences
    q0, qd = np.array([0.02, -0.01, 0.62, 0.05, -0.04, 0.03]), np.array([0.1, -0.05, 0.08, 0.3, 0.2, -0.25])
    Jinv, J, _ = eng.jacobian(q0)
    rd = np.array(Jinv).reshape(6, 6) @ qd
    idp = eng.inverse_dynamics_at_pose(q0, rd, np.zeros(6))
    jac = eng.jacobians(q0, rd)

    def energy(q, v):
        Jq = eng.jacobians(q, np.array(eng.jacobian(q)[0]).reshape(6, 6) @ v)
        T = V = 0.0
        for body in eng.bodies:
            I = np.array(body.inertia)
            T += 0.5 * body.mass * Jq.v[body.name] @ Jq.v[body.name] + 0.5 * Jq.w[body.name] @ I @ Jq.w[body.name]
        V = sum(body.mass * 9.81 * com_z for body, com_z in zip(eng.bodies, _com_heights(eng, q)))
        return T + V

    h = 1e-6
    # q moves with qd and accelerates with the "Jdot rho_dot" of rho_ddot = 0
    qa = q0 + h * qd + 0.5 * h * h * jac.Jdot
    qb = q0 - h * qd + 0.5 * h * h * jac.Jdot
    va, vb = qd + h * jac.Jdot, qd - h * jac.Jdot
    dE = (energy(qa, va) - energy(qb, vb)) / (2 * h)
    assert float(idp.t_rho @ rd) == pytest.approx(dE, rel=1e-5)


def _com_heights(eng, q):
    ev = eng.description.evaluate(list(q))
    return [
        float(o[2] + R[2][0] * b.com[0] + R[2][1] * b.com[1] + R[2][2] * b.com[2])
        for b, (o, R) in zip(eng.bodies, ev.frames)
    ]


def test_a_6pus_from_a_file_gives_the_slider_positions(tmp_path):
    text = changed('template = "UPS"', 'template = "PUS"', HEXAPOD).replace(
        'bodies.cylinder = { mass = "m_c", com = [0.15, 0.0, 0.0], inertia = [[0.001, 0, 0], [0, 0.01, 0], [0, 0, '
        "0.01]] }\n"
        'bodies.rod = { mass = "0.5 * m_c", com = [-0.1, 0.0, 0.0] }',
        'bodies.link = { mass = "m_c", com = [0.3, 0, 0] }',
    )
    text = changed("[parameters]\n", '[parameters]\nLp = { value = 0.6, unit = "m", source = "assumed" }\n', text)
    text = changed("stroke = [0.4, 1.0]", "stroke = [-0.3, 0.5]", text).replace('z = "h0"', 'z = "h0 + 0.3"')
    file = load(written(tmp_path, text + hexapod_legs("PUS"), "pus.toml"))
    eng = Engine(file.describe(), g=9.81)
    rng = np.random.default_rng(5)
    for _ in range(10):
        q = np.array([0.0, 0.0, 0.9, 0.0, 0.0, 0.0]) + rng.uniform(-1, 1, 6) * [0.05, 0.05, 0.05, 0.1, 0.1, 0.1]
        R = rot(*q[3:])
        own = []
        for b, s in points(file, file.values()):
            S = q[:3] + R @ s
            # slider at b + rho e_z, |S - slider| = Lp, the lower root
            dz, horizontal2 = S[2] - b[2], float(np.sum((S[:2] - b[:2]) ** 2))
            own.append(dz - math.sqrt(0.36 - horizontal2))
        np.testing.assert_allclose(eng.ik(q), own, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(eng.dk(own, file.describe().topology.home)[0], q, atol=1e-11)


RPS = """
[mechanism]
name = "3RPS"
coordinates = ["z", "psi", "theta"]
gravity = "g"
home = { z = 0.45, psi = 0.0, theta = 0.0 }

[parameters]
H = { value = 0.4, unit = "m", source = "assumed" }
r = { value = 0.25, unit = "m", source = "assumed" }
g = { value = 9.81, unit = "m/s2", source = "standard gravity" }

[leg]
template = "RPS"
base_radius = "H"
platform_radius = "r"
drive = { joint = "P", kind = "linear", stroke = [0.3, 0.7] }

[[legs]]
angle = 0.0
[[legs]]
angle = "radians(120)"
[[legs]]
angle = "radians(240)"

[[bodies]]
name = "platform"
mass = 3.0
"""


def test_a_3rps_from_a_file_gives_the_leg_lengths_with_its_parasitic_motion(tmp_path):
    file = load(written(tmp_path, RPS, "rps.toml"))
    desc = file.describe()
    eng = Engine(desc, g=9.81)
    alpha = np.radians([0.0, 120.0, 240.0])
    for q in [(0.45, 0.0, 0.0), (0.43, 0.08, -0.05), (0.5, -0.1, 0.12)]:
        z, psi, theta = q

        def S(x, y, phi, z=z, psi=psi, theta=theta):
            R = rot(psi, theta, phi)
            return [np.array([x, y, z]) + R @ (0.25 * np.array([math.cos(a), math.sin(a), 0.0])) for a in alpha]

        def residual(u):
            return np.array([Si @ np.array([-math.sin(a), math.cos(a), 0.0]) for Si, a in zip(S(*u), alpha)])

        u = np.zeros(3)
        for _ in range(30):  # Newton on S_i . t_i = 0, finite-difference Jacobian
            J = np.column_stack([(residual(u + e) - residual(u - e)) / 2e-7 for e in np.eye(3) * 1e-7])
            u = u - np.linalg.solve(J, residual(u))
        own = [np.linalg.norm(Si - 0.4 * np.array([math.cos(a), math.sin(a), 0.0])) for Si, a in zip(S(*u), alpha)]
        np.testing.assert_allclose(eng.ik(q), own, rtol=1e-12)
        np.testing.assert_allclose(eng.pose(q), [u[0], u[1], z, psi, theta, u[2]], atol=1e-12)
        np.testing.assert_allclose(eng.dk(own)[0], q, atol=1e-11)


# ---- bad files ---------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "old, new, words",
    [
        # a leg that does not close at home
        (
            'name = "leg_1"',
            'name = "leg_1"\nbase_radius = "H + L"',
            r"bad.toml: leg 'leg_1' \(PRS\) does not close at the home pose \(z = 0.405147 m, psi = 0 rad, theta = 0 "
            r"rad\): "
            r"pose unreachable: leg 1 would need a horizontal reach of 0.31 m > L = 0.26 m",
        ),
        # the driven joint missing, doubled, or not drivable
        (
            'drive = { joint = "P", kind = "linear", stroke = [0.0, 0.3] }',
            "",
            r"bad.toml: leg 'leg_1' \(PRS\): no driven joint: expected exactly one",
        ),
        (
            'drive = { joint = "P", kind = "linear", stroke = [0.0, 0.3] }',
            'drives = [{ joint = "P", kind = "linear", stroke = [0.0, 0.3] }, { joint = "R", kind = "rotary", stroke '
            "= [-1, 1] }]",
            r"bad.toml: leg 'leg_1' \(PRS\): 2 driven joints: expected exactly one",
        ),
        (
            'drive = { joint = "P", kind = "linear"',
            'drive = { joint = "S", kind = "linear"',
            r"bad.toml: leg 'leg_1' \(PRS\): drive joint 'S': expected P",
        ),
        (
            'drive = { joint = "P", kind = "linear"',
            'drive = { joint = "P", kind = "rotary"',
            r"bad.toml: leg 'leg_1' \(PRS\): drive kind 'rotary': joint P is linear",
        ),
        # a number of drives that does not match the coordinates
        (
            'coordinates = ["z", "psi", "theta"]',
            'coordinates = ["z", "psi"]',
            r"bad.toml: 3 drives \(one per leg\) for 2 coordinates \(z, psi\): expected one driven joint per "
            r"coordinate",
        ),
        (
            'coordinates = ["z", "psi", "theta"]',
            'coordinates = ["x", "psi", "theta"]',
            r"bad.toml: \[mechanism\] coordinates x, psi, theta: legs of the plane family \(PRS\) need the coordinates "
            r"z, psi, theta",
        ),
        # units of the wrong dimension
        (
            'H = { value = 0.4, unit = "m"',
            'H = { value = 0.4, unit = "kg"',
            r"bad.toml: leg 'leg_1' \(PRS\): base_radius: expression 'H' is in kg: expected m \(its parameters' units: "
            r"H \[kg\]\)",
        ),
        (
            'I_leg = { value = 0.0003943333333333334, unit = "kg.m2"',
            'I_leg = { value = 0.0003943333333333334, unit = "kg"',
            r"bad.toml: leg 'leg_1' \(PRS\): body 'leg_1' \(part link\): inertia row 2\[1\]: expression 'I_leg' is in "
            r"kg: "
            r"expected kg.m2",
        ),
        (
            'length = "L"',
            'length = "L + alpha_1"',
            r"expression 'L \+ alpha_1': m \+ rad: units of different dimensions",
        ),
        (
            'H = { value = 0.4, unit = "m"',
            'H = { value = 0.4, unit = "meters"',
            r"bad.toml: parameter 'H': unit 'meters'",
        ),
        # a singular home pose: two guides on top of each other
        (
            "alpha_2 = { value = 1.5707963267948966",
            "alpha_2 = { value = 0.0",
            r"bad.toml: the home pose \(z = 0.405147 m, psi = 0 rad, theta = 0 rad\) is not admissible: singular",
        ),
        # a stroke that excludes home
        (
            "stroke = [0.0, 0.3]",
            "stroke = [0.2, 0.3]",
            r"bad.toml: leg 'leg_1': its drive's stroke \[0.2, 0.3\] excludes home \(0.15 at the home pose",
        ),
        ("stroke = [0.0, 0.3]", "stroke = [0.3, 0.0]", r"drive stroke \[0.3, 0.0\]: expected \[lower, upper\] \[m\]"),
        # an expression outside the subset
        (
            'length = "L"',
            "length = \"__import__('os').getcwd()\"",
            r"bad.toml: leg 'leg_1' \(PRS\): length: expression .*: the call .* is outside the subset \(\+ - \* / \*\*",
        ),
        ('length = "L"', 'length = "L if H else r"', r"expression 'L if H else r': IfExp .* is outside the subset"),
        ('length = "L"', 'length = "L ** 0.5"', r"a power other than an integer literal 1..8 is outside the subset"),
        ('length = "L"', 'length = "[L][0]"', r"is outside the subset"),
        # an unknown parameter name
        (
            'length = "L"',
            'length = "L_leg"',
            r"bad.toml: leg 'leg_1' \(PRS\): length: expression 'L_leg': unknown parameter 'L_leg' \(parameters: H, "
            r"r, L,",
        ),
        (
            'com = ["payload_x", "payload_y", "payload_z"]',
            'com = ["payload_x", "payload_y", "payload_w"]',
            r"bad.toml: body 'payload': com\[2\]: expression 'payload_w': unknown parameter 'payload_w'",
        ),
        # parameters without a source, unknown keys, an unknown template
        ('source = "Paper section 3: leg length"', 'source = " "', r"bad.toml: parameter 'L': expected its source"),
        (
            'template = "PRS"',
            'template = "PPS"',
            r"bad.toml: leg 1: template 'PPS': expected one of PRS, RPS, UPS, PUS",
        ),
        (
            'inclination = "beta"',
            'inclination = "beta"\nwidth = 0.1',
            r"bad.toml: leg 'leg_1' \(PRS\): unknown 'width'",
        ),
    ],
)
def test_a_bad_description_is_refused_naming_the_file_the_part_and_what_was_expected(tmp_path, old, new, words):
    path = written(tmp_path, changed(old, new))
    with pytest.raises(DescriptionError, match=words):
        load(path)


def test_a_bad_extension_and_bad_toml_are_refused(tmp_path):
    written(tmp_path, BASE, "3PRS_T.toml")
    path = written(tmp_path, 'extends = "3PRS_T.toml"\n[parameters]\nHx = { value = 1.0, unit = "m", source = "x" }\n')
    with pytest.raises(DescriptionError, match=r"bad.toml: parameter 'Hx' is not one of 3PRS_T.toml's"):
        load(path)
    with pytest.raises(DescriptionError, match=r"bad.toml: not valid TOML"):
        load(written(tmp_path, "[mechanism\n"))
    with pytest.raises(DescriptionError, match=r"missing.toml: cannot be read"):
        load(tmp_path / "missing.toml")


def test_a_parameter_set_without_a_parameter_the_description_uses_is_refused_by_name():
    file = load("3PRS_T")
    values = file.values()
    del values["m_leg"]
    with pytest.raises(ParameterError, match=r"mechanism: missing parameter 'm_leg' \[kg\] of the 3PRS description"):
        file.describe(values, owner="mechanism")
    file.describe(values, masses=False)  # a kinematic model needs only the geometry


def test_expressions_evaluate_in_the_subset_with_their_dimensions():
    units = {"L": "m", "a": "deg", "m": "kg"}
    e = Expression("0.5 * L**2 * cos(radians(a)) + sqrt(L**2) - -L", "here", units)
    assert e({"L": 2.0, "a": 60.0, "m": 1.0}) == pytest.approx(0.5 * 4 * 0.5 + 2 + 2, rel=1e-15)
    assert e.names == {"L", "a"}
    Expression("m * L**2 / 12", "here", units).check(units, "kg.m2")
    with pytest.raises(DescriptionError, match="sin of kg"):
        Expression("sin(m)", "here", units).check(units, "1")


def test_a_parameter_in_deg_reaches_the_description_in_deg_through_a_set(tmp_path, monkeypatch):
    """A description parameter in deg (the test hexapod's gap, 12 deg) written to its geometry set with that unit:
    the SSP reader gives the value in coherent SI (rad), but the description's expressions read it in degrees; the
    system's topology (its home pose: z = R_b cos(gap) here) read from the sets is the file's own."""
    from fmus.mechanism import designs
    from mast.core import description_sets, ssv
    from mast.core.systems import MAST, Part, topology

    text = HEXAPOD.replace('name = "6UPS"', 'name = "6UPS_gap"').replace('z = "h0"', 'z = "Rb * cos(radians(gap))"')
    path = tmp_path / "6UPS_gap.toml"
    path.write_text(text + hexapod_legs("UPS"), encoding="utf-8")
    monkeypatch.setitem(designs.KINEMATICS, "6UPS_gap", path)
    file = load(path)
    (tmp_path / "resources").mkdir()
    for name, content in (("geometry", description_sets.geometry), ("masses", description_sets.masses)):
        rows, comment = content(file)
        ssv.write(
            tmp_path / "resources" / f"{name}.ssv",
            ssv.parameter_set(name, {n: v for n, v, _, _ in rows}, {n: u for n, _, u, _ in rows if u}, {}, comment),
        )
    assert ssv.read_values(tmp_path / "resources" / "geometry.ssv")["gap"] == pytest.approx(math.radians(12.0))
    system = dataclasses.replace(MAST, mechanism=Part("X.fmu", ("resources/geometry.ssv", "resources/masses.ssv")))
    home = topology(system, tmp_path).home
    assert home[2] == pytest.approx(0.5 * math.cos(math.radians(12.0)), rel=1e-14)
    assert home == file.describe().topology.home
