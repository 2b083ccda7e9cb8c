"""The system SSDs generated from a system description (mast.core.systems), the parameter sets
written from the mechanism description files (mast.core.description_sets), and the SSD and SSV
modules that write them (mast.core.ssd, mast.core.ssv)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from fmus.mechanism.description import load
from fmus.mechanism.topology import POSE, Coordinate, Drive, Topology
from mast.core import ssd, ssv
from mast.core.description_sets import SETS, differences
from mast.core.designs import DESIGNS, STANDALONES, variant
from mast.core.ssp import read_ssd, validate_ssd_schema
from mast.core.ssv import SSPFormatError
from mast.core.systems import DRIVE_FORCES, MAST, STANDALONE, generate, system_ssd, topology

ROOT = Path(__file__).resolve().parents[1]
SSP = ROOT / "ssp"


def _system(tmp_path: Path, data: bytes, name: str = "x.ssd"):
    """``data`` as an .ssd beside the project's parameter sets, read by the reader (which checks every
    connection names declared connectors) and by the schema."""
    if not (tmp_path / "resources").exists():
        (tmp_path / "resources").symlink_to(SSP / "resources")
    (tmp_path / name).write_bytes(data)
    assert validate_ssd_schema(tmp_path / name) == []
    return read_ssd(tmp_path / name)


def _semantics(system) -> tuple:
    comps = {
        n: (c.source, c.step_size, c.inputs, c.outputs, c.bindings, c.ratings, c.parameters)
        for n, c in system.components.items()
    }
    return (comps, system.connections, system.system_inputs, system.base_step, system.start_time, system.stop_time)


@pytest.mark.parametrize("description", [MAST, STANDALONE, *STANDALONES], ids=lambda d: d.name)
def test_committed_system_is_what_the_generator_writes(description):
    assert description.path.read_bytes() == generate(description), (
        f"{description.path.name} is stale: run python -m mast.core.variants"
    )


def test_generated_default_system_reads_as_the_committed_one(tmp_path):
    generated = _system(tmp_path, generate(MAST))
    committed = read_ssd(SSP / "MAST.ssd")
    assert _semantics(generated) == _semantics(committed)
    # the 3PRS: three actuators, 3 pose commands + 12 connections per drive
    assert [n for n in generated.components if n.startswith("actuator_")] == ["actuator_1", "actuator_2", "actuator_3"]
    assert len(generated.connections) == 3 + 12 * 3 == 39
    assert all(generated.components[f"actuator_{k}"].ratings == "resources/drive_ratings.ssv" for k in (1, 2, 3))


def test_topology_of_the_default_system_is_the_3prs():
    shape = topology(MAST)
    assert (shape.name, shape.names, shape.joints) == ("3PRS", ("z", "psi", "theta"), ("rho_1", "rho_2", "rho_3"))


def _expected_connections(names, n, source=""):
    out = {(source, f"{c}_cmd", "controller", f"{c}_cmd") for c in names}
    for k in range(1, n + 1):
        out |= {
            ("controller", f"i_cmd_{k}", f"actuator_{k}", "i_cmd"),
            (f"actuator_{k}", "rho", "controller", f"rho_{k}"),
            (f"actuator_{k}", "omega_m", "controller", f"omega_m_{k}"),
            (f"actuator_{k}", "rho", "mechanism", f"rho_{k}"),
            (f"actuator_{k}", "rho_dot", "mechanism", f"rho_dot_{k}"),
            (f"actuator_{k}", "rho_ddot", "mechanism", f"rho_ddot_{k}"),
            *((f"actuator_{k}", q, "mechanism", f"{q}_{k}") for q in DRIVE_FORCES),
            ("mechanism", f"Fc_{k}", f"actuator_{k}", "F"),
            ("mechanism", f"Mc_{k}", f"actuator_{k}", "M_carried"),
        }
    return out


HEXAPOD = Topology(
    "hexapod",
    tuple(Coordinate(c) for c in POSE),
    tuple(Drive(f"rho_{k}", "linear", (0.0, 0.2)) for k in range(1, 7)),
    (0.0, 0.0, 0.5, 0.0, 0.0, 0.0),
)


@pytest.mark.parametrize("description", [MAST, STANDALONE], ids=lambda d: d.name)
def test_a_six_drive_topology_gives_six_actuators_and_every_connection(tmp_path, description):
    system = _system(tmp_path, system_ssd(description, HEXAPOD).to_bytes())
    actuators = sorted(n for n in system.components if n.startswith("actuator_"))
    assert actuators == [f"actuator_{k}" for k in range(1, 7)]
    source = "trajectory" if description.trajectory else ""
    got = {(c.start_element, c.start_connector, c.end_element, c.end_connector) for c in system.connections}
    assert got == _expected_connections(POSE, 6, source) and len(system.connections) == 6 + 12 * 6
    assert system.system_inputs == ([] if source else [f"{c}_cmd" for c in POSE])
    mech = system.components["mechanism"]
    assert mech.inputs == [f"{q}_{k}" for q in ("rho", "rho_dot", "rho_ddot", *DRIVE_FORCES) for k in range(1, 7)]
    ks = range(1, 7)
    assert mech.outputs == [f"F_{k}" for k in ks] + list(POSE) + [f"Fc_{k}" for k in ks] + [f"Mc_{k}" for k in ks]
    assert system.components["controller"].inputs[:6] == [f"{c}_cmd" for c in POSE]
    for k in range(1, 7):  # each actuator bound like the 3PRS's, with its ratings and step size
        a = system.components[f"actuator_{k}"]
        assert (a.source, a.step_size, a.ratings) == (
            "resources/MastActuator.fmu",
            1e-4,
            "resources/drive_ratings.ssv",
        )
        assert [s for s, _ in a.bindings] == list(MAST.actuator.bindings)


def test_rotary_drives_give_angular_joint_units():
    delta = Topology(
        "delta",
        (Coordinate("x"), Coordinate("y"), Coordinate("z")),
        tuple(Drive(f"rho_{k}", "rotary", (-1.0, 1.0)) for k in (1, 2, 3)),
        (0.0, 0.0, -0.3),
    )
    doc = system_ssd(MAST, delta)
    units = {(c.name, k.name): k.unit for c in doc.system.elements for k in c.connectors}
    assert units[("mechanism", "rho_2")] == "rad" and units[("mechanism", "rho_ddot_3")] == "rad/s2"
    assert units[("mechanism", "F_1")] == "N.m" and units[("actuator_1", "F")] == "N.m"
    assert units[("controller", "x_cmd")] == "m" and units[("controller", "rho_cmd_1")] == "rad"
    assert "Rotary axis 2" in doc.system.elements[2].comment


def test_parameter_set_round_trip(tmp_path):
    written = ssv.parameter_set(
        "trial",
        {"m": 2.5, "n": 3, "on": True, "kind": "3PRS -- a <note>", "J": 1e-5},
        {"m": "g", "J": "kg.m2"},
        {"m": "a mass", "kind": "text"},
        "a comment -- with dashes",
    )
    path = ssv.write(tmp_path / "trial.ssv", written)
    back = ssv.read(path)
    assert back.name == "trial" and list(back.parameters) == ["m", "n", "on", "kind", "J"]
    assert back.parameters["m"].value == pytest.approx(2.5e-3) and back.parameters["m"].written == 2.5
    assert (back.parameters["n"].value, back.parameters["on"].value) == (3, True)
    assert back.parameters["kind"].value == "3PRS -- a <note>" and back.parameters["m"].source == "a mass"
    assert set(back.units) == {"g", "kg.m2"} and back.units["g"].factor == pytest.approx(1e-3)
    assert back.comment.strip() == "a comment - - with dashes"


def test_an_ssd_round_trips_through_its_classes():
    document = ssd.read(SSP / "MAST_computed_torque.ssd")
    assert ssd.read(document.to_bytes(), "again").system == document.system


def test_writing_what_the_reader_does_not_model_is_refused():
    text = (
        (SSP / "MAST.ssd")
        .read_text()
        .replace(
            "<ssd:Connections>",
            '<ssd:SignalDictionaries><ssd:SignalDictionary name="d"/></ssd:SignalDictionaries><ssd:Connections>',
            1,
        )
    )
    document = ssd.read(text.encode(), "user.ssd")
    with pytest.raises(SSPFormatError, match="SignalDictionaries"):
        document.to_bytes()


# ---- the parameter sets written from the description files ---------------------------------------------
@pytest.mark.parametrize("described", SETS, ids=lambda s: s.name)
def test_committed_set_is_what_its_description_gives(described):
    assert not differences(described), "\n".join(differences(described) + ["run python -m mast.core.variants"])


@pytest.mark.parametrize(
    "edit, words",
    [
        (
            lambda t: t.replace('value="0.4"', 'value="0.41"'),
            r"geometry_3prs\.ssv .*parameter 'H' is 0\.41 m, the "
            r"description gives 0\.4 m",
        ),
        (
            lambda t: t.replace(
                'unit="rad"/></ssv:Parameter>\n    <ssv:Parameter name="alpha_2"',
                'unit="deg"/></ssv:Parameter>\n    <ssv:Parameter name="alpha_2"',
            ),
            r"parameter 'alpha_1' is 0\.0 deg, the description gives 0\.0 rad",
        ),
        (
            lambda t: t.replace("Paper section 3: leg length", "a guess"),
            r"parameter 'L': description 'a guess', its source",
        ),
        (
            lambda t: t.replace('<ssv:String value="3PRS"/>', '<ssv:String value="3RPS"/>'),
            r"parameter 'kinematics' is '3RPS'",
        ),
        (
            lambda t: t.replace('<ssv:Parameter name="beta"', '<ssv:Parameter name="gamma"'),
            r"parameter 'gamma' is not in the description\n.*parameter 'beta' is missing",
        ),
        (lambda t: t.replace("Bound to the mechanism", "Bound to everything"), r"same parameters, but not the file"),
    ],
)
def test_a_committed_set_that_differs_from_its_description_is_named(tmp_path, edit, words):
    geometry = next(s for s in SETS if s.name == "geometry_3prs")
    text = geometry.path.read_text()
    assert edit(text) != text
    (tmp_path / "geometry_3prs.ssv").write_text(edit(text))
    found = "\n".join(differences(geometry, tmp_path / "geometry_3prs.ssv"))
    assert re.search(words, found), found


def test_every_set_bound_to_a_designs_mechanism_gives_its_description_values():
    """Read as the SSP reader reads a system: each design's mechanism gets its description file's values (the same
    floats), the 3PRS's name as ``kinematics``, and ``attached`` and ``T_mech`` from attached.ssv (attached 0 for
    actuators_only only; the update period 0.2 ms for all)."""
    for d in DESIGNS:
        file = load(d.name if d.name != "actuators_only" else "3PRS_T")
        merged = {}
        for source in variant(d).mechanism.bindings:
            merged.update({k: p.value for k, p in ssv.read(SSP / source).parameters.items()})
        assert merged.pop("kinematics") == file.name and merged.pop("attached") == int(d.name != "actuators_only")
        assert merged.pop("T_mech") == 1e-3
        assert merged == file.values(), d.name


def test_the_home_pose_and_the_inclined_guides_gravity_are_derived_from_their_files():
    home = {k: p for k, p in ssv.read(SSP / "resources" / "home_3prs.ssv").parameters.items()}
    assert tuple(home[f"{c}_home"].value for c in ("z", "psi", "theta")) == load("3PRS_T").describe().topology.home
    assert all(p.source.startswith("Home pose, derived from 3PRS_T.toml") for p in home.values())
    inclined = load("3PRS_inclined").values()
    g_guide = ssv.read(SSP / "resources" / "guide_inclined.ssv").parameters["g_guide"]
    assert g_guide.value == pytest.approx(inclined["g"] * math.cos(inclined["beta"]), rel=1e-15)
    assert g_guide.value == pytest.approx(9.81 * math.cos(math.radians(15.0)), rel=1e-15)
