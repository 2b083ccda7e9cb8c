"""Reading the system structure: the default SSD, bindings, step sizes and malformed input."""

from __future__ import annotations

import zipfile
from pathlib import Path

import pytest

from mast.core.run import parse_overrides
from mast.core.ssp import SSPArchive, read_ssd, safe_extract, validate_ssd_schema
from mast.core.ssv import SSPFormatError, parse_ssv

ROOT = Path(__file__).resolve().parents[1]
SSD = ROOT / "ssp" / "MAST.ssd"


def test_default_ssd_is_schema_valid_and_complete():
    assert validate_ssd_schema(SSD) == []
    system = read_ssd(SSD)
    assert set(system.components) == {"controller", "actuator_1", "actuator_2", "actuator_3", "mechanism"}
    # issue 27's exchange: every component at the current-loop cycle T_cur = 100 us (the controller's laws tick at
    # T_pos = T_vel = 1 ms inside it, the mechanism's full update every T_mech = 1 ms: docs/interfaces.md "Timing")
    assert system.base_step == pytest.approx(1e-4)
    assert all(c.step_size == pytest.approx(1e-4) for c in system.components.values())
    assert system.system_inputs == ["z_cmd", "psi_cmd", "theta_cmd"]
    # every component input is fed by exactly one connection
    for name, comp in system.components.items():
        for connector in comp.inputs:
            feeds = [c for c in system.connections if c.end_element == name and c.end_connector == connector]
            assert len(feeds) == 1, f"{name}.{connector} fed {len(feeds)} times"


def test_every_parameter_has_a_unit_or_is_dimensionless_and_a_source():
    for ssv in (ROOT / "ssp" / "resources").glob("*.ssv"):
        for name, p in parse_ssv(ssv).items():
            assert p.source, f"{ssv.name}: {name} has no source"
            if isinstance(p.value, float):
                assert p.unit, f"{ssv.name}: {name} has no unit"


def test_bindings_apply_in_order_later_overrides_earlier(tmp_path):
    text = SSD.read_text().replace(
        '<ssd:ParameterBinding source="resources/actuator_manufacturer.ssv"/>',
        '<ssd:ParameterBinding source="resources/actuator_manufacturer.ssv"/>'
        '<ssd:ParameterBinding source="resources/actuator_identified.ssv"/>',
        1,
    )
    (tmp_path / "resources").symlink_to(ROOT / "ssp" / "resources")
    (tmp_path / "x.ssd").write_text(text)
    system = read_ssd(tmp_path / "x.ssd")
    assert system.components["actuator_1"].parameters["tau_c"] == pytest.approx(0.0718)
    assert system.components["actuator_2"].parameters["tau_c"] == pytest.approx(0.019278, rel=1e-4)


@pytest.mark.parametrize(
    "edit, message",
    [
        (
            lambda s: s.replace(
                'endElement="mechanism" endConnector="rho_1"', 'endElement="mechanism" endConnector="rho_9"'
            ),
            "mechanism.rho_9",
        ),
        (
            lambda s: s.replace(
                'startElement="controller" startConnector="i_cmd_1"',
                'startElement="controler" startConnector="i_cmd_1"',
            ),
            "controler",
        ),
        (lambda s: s.replace('<osp:StepSizeHint value="0.0001"/>', '<osp:StepSizeHint value="-1"/>'), "StepSizeHint"),
        (lambda s: s.replace("resources/mass_3prs.ssv", "resources/missing.ssv"), "missing.ssv"),
        (lambda s: s[: len(s) // 2], "cannot read"),
    ],
)
def test_malformed_ssd_gives_a_clear_error(tmp_path, edit, message):
    (tmp_path / "resources").symlink_to(ROOT / "ssp" / "resources")
    (tmp_path / "bad.ssd").write_text(edit(SSD.read_text()))
    with pytest.raises(SSPFormatError, match=message):
        read_ssd(tmp_path / "bad.ssd")


def test_malformed_ssv_gives_a_clear_error(tmp_path):
    bad = tmp_path / "bad.ssv"
    bad.write_text((ROOT / "ssp" / "resources" / "mass_3prs.ssv").read_text().replace('value="2.06"', 'value="heavy"'))
    with pytest.raises(SSPFormatError, match="m_platform.*heavy"):
        parse_ssv(bad)


def test_archive_entries_outside_target_are_refused(tmp_path):
    for evil in ("../escape.txt", "/abs/escape.txt"):
        archive = tmp_path / "evil.ssp"
        with zipfile.ZipFile(archive, "w") as z:
            z.writestr("SystemStructure.ssd", "<x/>")
            z.writestr(evil, "boom")
        with pytest.raises(SSPFormatError, match="outside the target"):
            safe_extract(archive, tmp_path / "out")
        assert not (tmp_path / "escape.txt").exists()


def test_corrupt_and_incomplete_archives_are_named(tmp_path):
    junk = tmp_path / "junk.ssp"
    junk.write_bytes(b"not a zip")
    with pytest.raises(SSPFormatError, match="junk.ssp.*not a readable zip"):
        SSPArchive(junk)
    no_fmu = tmp_path / "nofmu.ssp"
    with zipfile.ZipFile(no_fmu, "w") as z:
        z.write(SSD, "SystemStructure.ssd")
        for ssv in (ROOT / "ssp" / "resources").glob("*.ssv"):
            z.write(ssv, f"resources/{ssv.name}")
    with pytest.raises(SSPFormatError, match="controller.*MastController.fmu is missing"):
        SSPArchive(no_fmu)


def test_parse_overrides():
    assert parse_overrides(["actuator_1.tau_c=0.07", "actuator_2.n_dof=1", "x.s=abc"]) == {
        "actuator_1": {"tau_c": 0.07},
        "actuator_2": {"n_dof": 1},
        "x": {"s": "abc"},
    }
    with pytest.raises(ValueError, match="ELEMENT.PARAMETER=VALUE"):
        parse_overrides(["tau_c=0.07"])


def test_bound_names_a_component_lacks_are_ignored_unless_no_component_of_the_set_has_them():
    """SSP 1.0: a bound name the component does not have is ignored (the plant's actuator set also
    parametrises the computed-torque controller's model); a name no component of its set has is a typo."""
    from mast.core.build import block_class
    from mast.core.ssp import applicable_parameters
    from mast.core.ssv import SSPFormatError

    system = read_ssd(ROOT / "ssp" / "MAST_computed_torque.ssd")
    names = {c: {p.name for p in block_class(Path(s.source).stem).PARAMETERS} for c, s in system.components.items()}
    bound = applicable_parameters(system, names)
    assert "R" in system.components["controller"].parameters and "R" not in bound["controller"]
    assert bound["controller"]["k_T"] == bound["actuator_1"]["k_T"]
    assert bound["controller"]["L"] == bound["mechanism"]["L"]  # the later (geometry) binding wins
    source, values = system.components["controller"].bindings[-1]
    system.components["controller"].bindings[-1] = (source, {**values, "omega_nn": 1.0})
    with pytest.raises(
        SSPFormatError, match=r"controller_computed_torque.ssv: 'omega_nn' is a parameter of no component"
    ):
        applicable_parameters(system, names)
