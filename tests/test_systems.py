"""The system SSDs generated from a system description (mast.core.systems), and the SSD and SSV
modules that write them (mast.core.ssd, mast.core.ssv)."""
from __future__ import annotations

from pathlib import Path

import pytest

from fmus.mechanism.topology import POSE, Coordinate, Drive, Topology
from mast.core import ssd, ssv
from mast.core.ssp import read_ssd, validate_ssd_schema
from mast.core.ssv import SSPFormatError
from mast.core.systems import MAST, STANDALONE, generate, system_ssd, topology

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
    comps = {n: (c.source, c.step_size, c.inputs, c.outputs, c.bindings, c.ratings, c.parameters)
             for n, c in system.components.items()}
    return (comps, system.connections, system.system_inputs, system.base_step, system.start_time, system.stop_time)


@pytest.mark.parametrize("description", [MAST, STANDALONE], ids=lambda d: d.name)
def test_committed_system_is_what_the_generator_writes(description):
    assert description.path.read_bytes() == generate(description), \
        f"{description.path.name} is stale: run python -m mast.core.variants"


def test_generated_default_system_reads_as_the_committed_one(tmp_path):
    generated = _system(tmp_path, generate(MAST))
    committed = read_ssd(SSP / "MAST.ssd")
    assert _semantics(generated) == _semantics(committed)
    # the 3PRS: three actuators, 3 pose commands + 7 connections per drive
    assert [n for n in generated.components if n.startswith("actuator_")] == ["actuator_1", "actuator_2", "actuator_3"]
    assert len(generated.connections) == 3 + 7 * 3 == 24
    assert all(generated.components[f"actuator_{k}"].ratings == "resources/drive_ratings.ssv" for k in (1, 2, 3))


def test_topology_of_the_default_system_is_the_3prs():
    shape = topology(MAST)
    assert (shape.name, shape.names, shape.joints) == ("3PRS", ("z", "psi", "theta"), ("rho_1", "rho_2", "rho_3"))


def _expected_connections(names, n, source=""):
    out = {(source, f"{c}_cmd", "controller", f"{c}_cmd") for c in names}
    for k in range(1, n + 1):
        out |= {("controller", f"i_cmd_{k}", f"actuator_{k}", "i_cmd"),
                (f"actuator_{k}", "rho", "controller", f"rho_{k}"),
                (f"actuator_{k}", "omega_m", "controller", f"omega_m_{k}"),
                (f"actuator_{k}", "rho", "mechanism", f"rho_{k}"),
                (f"actuator_{k}", "rho_dot", "mechanism", f"rho_dot_{k}"),
                (f"actuator_{k}", "rho_ddot", "mechanism", f"rho_ddot_{k}"),
                ("mechanism", f"F_{k}", f"actuator_{k}", "F")}
    return out


HEXAPOD = Topology("hexapod", tuple(Coordinate(c) for c in POSE),
                   tuple(Drive(f"rho_{k}", "linear", (0.0, 0.2)) for k in range(1, 7)), (0.0, 0.0, 0.5, 0.0, 0.0, 0.0))


@pytest.mark.parametrize("description", [MAST, STANDALONE], ids=lambda d: d.name)
def test_a_six_drive_topology_gives_six_actuators_and_every_connection(tmp_path, description):
    system = _system(tmp_path, system_ssd(description, HEXAPOD).to_bytes())
    actuators = sorted(n for n in system.components if n.startswith("actuator_"))
    assert actuators == [f"actuator_{k}" for k in range(1, 7)]
    source = "trajectory" if description.trajectory else ""
    got = {(c.start_element, c.start_connector, c.end_element, c.end_connector) for c in system.connections}
    assert got == _expected_connections(POSE, 6, source) and len(system.connections) == 6 + 7 * 6
    assert system.system_inputs == ([] if source else [f"{c}_cmd" for c in POSE])
    mech = system.components["mechanism"]
    assert mech.inputs == [f"{q}_{k}" for q in ("rho", "rho_dot", "rho_ddot") for k in range(1, 7)]
    assert mech.outputs == [f"F_{k}" for k in range(1, 7)] + list(POSE)
    assert system.components["controller"].inputs[:6] == [f"{c}_cmd" for c in POSE]
    for k in range(1, 7):   # each actuator bound like the 3PRS's, with its ratings and step size
        a = system.components[f"actuator_{k}"]
        assert (a.source, a.step_size, a.ratings) == ("resources/MastActuator.fmu", 0.001, "resources/drive_ratings.ssv")
        assert [s for s, _ in a.bindings] == list(MAST.actuator.bindings)


def test_rotary_drives_give_angular_joint_units():
    delta = Topology("delta", (Coordinate("x"), Coordinate("y"), Coordinate("z")),
                     tuple(Drive(f"rho_{k}", "rotary", (-1.0, 1.0)) for k in (1, 2, 3)), (0.0, 0.0, -0.3))
    doc = system_ssd(MAST, delta)
    units = {(c.name, k.name): k.unit for c in doc.system.elements for k in c.connectors}
    assert units[("mechanism", "rho_2")] == "rad" and units[("mechanism", "rho_ddot_3")] == "rad/s2"
    assert units[("mechanism", "F_1")] == "N.m" and units[("actuator_1", "F")] == "N.m"
    assert units[("controller", "x_cmd")] == "m" and units[("controller", "rho_cmd_1")] == "rad"
    assert "Rotary axis 2" in doc.system.elements[2].comment


def test_parameter_set_round_trip(tmp_path):
    written = ssv.parameter_set("trial", {"m": 2.5, "n": 3, "on": True, "kind": "3PRS -- a <note>", "J": 1e-5},
                                {"m": "g", "J": "kg.m2"}, {"m": "a mass", "kind": "text"}, "a comment -- with dashes")
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
    text = (SSP / "MAST.ssd").read_text().replace(
        "<ssd:Connections>", '<ssd:SignalDictionaries><ssd:SignalDictionary name="d"/></ssd:SignalDictionaries>'
        "<ssd:Connections>", 1)
    document = ssd.read(text.encode(), "user.ssd")
    with pytest.raises(SSPFormatError, match="SignalDictionaries"):
        document.to_bytes()
