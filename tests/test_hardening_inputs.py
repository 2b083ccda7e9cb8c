"""Bad input on the command line and in parameter sets: a clear error naming it, before any run."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

import mast.core.build as build_module
from fmus.common.parameters import exact_boolean, exact_integer
from mast.cli import main as cli_main
from mast.core.build import default_parameters
from mast.core.ssv import SSPFormatError, parse_ssv
from mast.core.units import UnitError, convert, parse_unit

ROOT = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------ integers and booleans
@pytest.mark.parametrize("value, expected", [(2, 2), (2.0, 2), ("3", 3), (" 4 ", 4), ("5e0", 5), (True, 1)])
def test_exact_integer_takes_whole_numbers(value, expected):
    assert exact_integer(value) == expected and isinstance(exact_integer(value), int)


@pytest.mark.parametrize("value", [2.5, "2.5", 0.5, float("inf"), float("nan"), "two", None, 2**31, -(2**31) - 1])
def test_exact_integer_refuses_fractions_and_what_a_c_int_cannot_hold(value):
    with pytest.raises(ValueError, match="not a whole number|not a number|integer range"):
        exact_integer(value)


@pytest.mark.parametrize("value", [0.5, 2, "yes", "0.5", None])
def test_exact_boolean_refuses_what_is_not_true_or_false(value):
    with pytest.raises(ValueError, match="not a boolean"):
        exact_boolean(value)


@pytest.mark.parametrize("kind, raw", [("Boolean", "0.5"), ("Boolean", "yes"), ("Integer", "2.5")])
def test_ssv_refuses_a_boolean_or_integer_that_is_not_one(kind, raw):
    ssv = (
        f'<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
        f'version="1.0" name="s"><ssv:Parameters><ssv:Parameter name="attached"><ssv:{kind} value="{raw}"/>'
        f"</ssv:Parameter></ssv:Parameters></ssv:ParameterSet>"
    )
    with pytest.raises(SSPFormatError, match=f"set.ssv: parameter 'attached': value '{raw}' is not a valid {kind}"):
        parse_ssv(ssv, origin="set.ssv")


# ------------------------------------------------------------------ units in parameter sets
@pytest.mark.parametrize("unit, value, si", [("g", 2060.0, 2.06), ("kg", 2.06, 2.06), ("mg", 2.06e6, 2.06)])
def test_ssv_units_are_converted_to_the_declared_unit(tmp_path, unit, value, si):
    ssd = _system_with(tmp_path, f'<ssv:Real value="{value!r}" unit="{unit}"/>')
    assert default_parameters("MastMechanism", ssd)["m_platform"] == pytest.approx(si, rel=1e-12)


@pytest.mark.parametrize(
    "unit, message",
    [
        (
            "s",
            r"mass_3prs.ssv: 'm_platform' is given in 's' \(dimension s\), but component 'mechanism' declares it in "
            r"'kg'",
        ),
        ("furlong", r"mass_3prs.ssv: parameter 'm_platform': unit 'furlong': 'furlong' is not a known unit symbol"),
    ],
)
def test_ssv_units_of_another_dimension_or_unknown_are_refused_by_name(tmp_path, unit, message):
    ssd = _system_with(tmp_path, f'<ssv:Real value="2.06" unit="{unit}"/>')
    with pytest.raises(SSPFormatError, match=message):
        default_parameters("MastMechanism", ssd)


def test_unit_notation():
    assert convert(1.0, parse_unit("g.cm2"), parse_unit("kg.m2")) == pytest.approx(1e-7)
    assert convert(30.0, parse_unit("mN.m"), parse_unit("N.m")) == pytest.approx(0.03)
    assert convert(180.0, parse_unit("deg"), parse_unit("rad")) == pytest.approx(3.141592653589793)
    assert parse_unit("V/(A.s)").dims == parse_unit("kg.m2.s-4.A-2").dims
    with pytest.raises(UnitError, match="dimension"):
        convert(1.0, parse_unit("Hz"), parse_unit("rad/s"))


def _system_with(tmp_path: Path, real: str) -> Path:
    """ssp/MAST.ssd with the platform mass of mass_3prs.ssv written as ``real``."""
    shutil.copytree(ROOT / "ssp" / "resources", tmp_path / "resources")
    shutil.copy(ROOT / "ssp" / "MAST.ssd", tmp_path / "MAST.ssd")
    ssv = tmp_path / "resources" / "mass_3prs.ssv"
    text = ssv.read_text()
    old = '<ssv:Real value="2.06" unit="kg"/>'
    assert old in text
    ssv.write_text(text.replace(old, real))
    return tmp_path / "MAST.ssd"


# ------------------------------------------------------------------ the command line
@pytest.fixture
def a_file(tmp_path) -> Path:
    path = tmp_path / "existing.txt"
    path.write_text("keep me")
    return path


@pytest.mark.parametrize(
    "argv, named",
    [
        (["run", "--stop-time", "inf"], "--stop-time: 'inf'"),
        (["run", "--stop-time", "nan"], "--stop-time: 'nan'"),
        (["run", "--stop-time", "0"], "--stop-time: '0'"),
        (["run", "--record-step", "-1"], "--record-step: '-1'"),
        (["run", "--amplitude", "nan"], "--amplitude: 'nan'"),
        (["run", "--frequency", "0"], "--frequency: '0': expected a positive, finite number of Hz"),
        (["run", "--frequency", "-2"], "--frequency: '-2'"),
        (["run", "--frequency", "inf"], "--frequency: 'inf'"),
        (["run", "--frequency", "nan"], "--frequency: 'nan'"),
        (["compare", "--mechanism", "a.fmu", "--out", "x", "--frequencies", "1", "0"], "--frequencies: '0'"),
        (["bench", "--stop-time", "inf"], "--stop-time: 'inf'"),
        (["hosts", "--stop-time", "-1"], "--stop-time: '-1'"),
        (["synthesize", "--out", "x", "--sample-time", "nan"], "--sample-time: 'nan'"),
        (["compare", "--mechanism", "a.fmu", "--out", "x", "--frequencies", "inf"], "--frequencies: 'inf'"),
        (["diagnose", "--measured", "m", "--out", "x", "--workers", "0"], "--workers: '0'"),
        (["diagnose", "--measured", "m", "--out", "x", "--holdout-fraction", "1.5"], "--holdout-fraction: '1.5'"),
        (["workspace", "3PRS_T", "--out", "x", "--step-z", "-0.01"], "--step-z: '-0.01'"),
        (["workspace", "3PRS_T", "--out", "x", "--payload", "nan"], "--payload: 'nan'"),
    ],
)
def test_cli_refuses_non_finite_and_non_positive_numbers(capsys, argv, named):
    with pytest.raises(SystemExit) as info:
        cli_main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert named in err and "Traceback" not in err


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "--out", "{file}"],
        ["run", "--out", "{file}/sub"],
        ["reproduce", "--out", "{file}"],
        ["batch", "config.toml", "--out", "{file}"],
        ["compare", "--mechanism", "a.fmu", "--out", "{file}"],
        ["synthesize", "--out", "{file}"],
        ["diagnose", "--measured", "m", "--out", "{file}"],
        ["fit-gains", "--out", "{file}"],
        ["import", "f.mat", "--map", "m.toml", "--out", "{file}"],
        ["replay", "a.ssp", "--measured", "m", "--out", "{file}"],
        ["workspace", "3PRS_T", "--out", "{file}"],
    ],
)
def test_cli_refuses_an_output_that_is_a_file_before_running(capsys, a_file, argv):
    argv = [a.format(file=a_file) for a in argv]
    with pytest.raises(SystemExit) as info:
        cli_main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "--out" in err and str(a_file) in err and "Traceback" not in err
    assert a_file.read_text() == "keep me"


@pytest.mark.parametrize(
    "argv, named",
    [
        (["synthesize", "--out", "{tmp}/x", "--noise", "tau_m=abc"], "--noise 'tau_m=abc'"),
        (["synthesize", "--out", "{tmp}/x", "--resolution", "rho=-1"], "--resolution 'rho=-1'"),
        (["synthesize", "--out", "{tmp}/x", "--tests", "z:0.005:nan"], "--tests item 'z:0.005:nan'"),
        (["synthesize", "--out", "{tmp}/x", "--tests", "z:abc:1"], "--tests item 'z:abc:1'"),
        (["synthesize", "--out", "{tmp}/x", "--tests", "z:0.005:1,theta:0.8:0"], "--tests item 'theta:0.8:0'"),
        (["synthesize", "--out", "{tmp}/x", "--tests", "z:0.005:-1"], "a frequency > 0 Hz"),
    ],
)
def test_cli_synthesize_options_name_the_bad_item(capsys, tmp_path, argv, named):
    assert cli_main([a.format(tmp=tmp_path) for a in argv]) == 2
    err = capsys.readouterr().err
    assert named in err and "Traceback" not in err
    assert not (tmp_path / "x").exists()


def test_a_number_for_a_string_parameter_is_its_text_on_both_routes():
    """--set actuator_1.J_chain=0.001 arrives as a number: the FMU route wrote str(value), the direct
    route refused it; both now take its exact text, and both refuse a boolean."""
    from fmus.common.parameters import Param, ParameterError, exact_string
    from mast.core.components import _FMI_VALUE

    spec = Param("J_chain", "kg.m2", "", kind=str)
    for value in (0.001, 3, "1e-3 2e-3"):
        assert spec.check(value) == _FMI_VALUE["String"](value) == exact_string(value)
    with pytest.raises(ParameterError, match="'J_chain' = True"):
        spec.check(True)
    with pytest.raises(ValueError, match="True is not a string"):
        _FMI_VALUE["String"](True)


def test_cli_check_mechanism_names_a_missing_fmu_without_a_traceback(capsys, tmp_path):
    missing = tmp_path / "nowhere.fmu"
    assert cli_main(["check-mechanism", str(missing)]) == 2
    err = capsys.readouterr().err
    assert f"{missing}: no such FMU file" in err and "Traceback" not in err


def test_cli_reproduce_names_a_missing_ssp_before_running_anything(capsys, tmp_path):
    """It ran its 82 co-simulations, each failing on the missing file, before saying so (and made --out)."""
    assert cli_main(["reproduce", str(tmp_path / "none.ssp"), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert f"{tmp_path / 'none.ssp'}: no such SSP file" in err and "sine tests" not in err
    assert not (tmp_path / "r").exists()


def test_the_default_build_folder_is_the_checkouts_or_else_the_current_directorys(tmp_path, monkeypatch):
    """After a plain `pip install .` the package lives in site-packages: `mast build` without --out writes
    into ./build, not there (an editable install keeps the checkout's build/)."""
    assert build_module.default_build_dir() == ROOT / "build"
    installed, work = tmp_path / "site-packages", tmp_path / "work"
    installed.mkdir()
    work.mkdir()
    monkeypatch.setattr(build_module, "REPO", installed)
    monkeypatch.chdir(work)
    assert build_module.default_build_dir() == work / "build"


def _system_with_inline_mass(tmp_path: Path, unit: str, units_section: str) -> Path:
    """ssp/MAST.ssd with one more binding of the mechanism: m_platform = 2060 ``unit`` inline, and
    ``units_section`` (an ssd:Units element, or nothing) before ssd:DefaultExperiment."""
    shutil.copytree(ROOT / "ssp" / "resources", tmp_path / "resources")
    text = (ROOT / "ssp" / "MAST.ssd").read_text()
    end = text.index("</ssd:ParameterBindings>", text.index('<ssd:Component name="mechanism"'))
    binding = (
        '<ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" name="inline">'
        f'<ssv:Parameters><ssv:Parameter name="m_platform"><ssv:Real value="2060.0" unit="{unit}"/>'
        "</ssv:Parameter></ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding>"
    )
    text = text[:end] + binding + text[end:]
    text = text.replace("<ssd:DefaultExperiment", units_section + "<ssd:DefaultExperiment", 1)
    (tmp_path / "MAST.ssd").write_text(text)
    return tmp_path / "MAST.ssd"


def test_units_an_ssd_defines_apply_to_its_inline_values_on_every_route(tmp_path):
    """SSP 1.0 ssd:Units: a unit the .ssd defines converts its inline values (read_ssd, and the flattened
    set mast build writes for third-party hosts); without the definition the unit is refused by name."""
    from lxml import etree

    from mast.core.build import block_class, flatten_bindings
    from mast.core.ssp import read_ssd

    units = '<ssd:Units><ssc:Unit name="gram_of_lab"><ssc:BaseUnit kg="1" factor="0.001"/></ssc:Unit></ssd:Units>'
    ssd = _system_with_inline_mass(tmp_path / "defined", "gram_of_lab", units)
    assert default_parameters("MastMechanism", ssd)["m_platform"] == pytest.approx(2.06, rel=1e-12)
    names = {
        c: {p.name: p.unit for p in block_class(Path(s.source).stem).PARAMETERS}
        for c, s in read_ssd(ssd).components.items()
    }
    _, sets = flatten_bindings(ssd, names)
    flat = parse_ssv(sets["resources/parameters/mechanism.ssv"])
    assert flat["m_platform"].value == pytest.approx(2.06, rel=1e-12) and flat["m_platform"].unit == "kg"
    etree.fromstring(sets["resources/parameters/mechanism.ssv"])  # well-formed
    undefined = _system_with_inline_mass(tmp_path / "undefined", "gram_of_lab", "")
    with pytest.raises(
        SSPFormatError, match=r"inline values of 'mechanism'\): parameter 'm_platform': unit 'gram_of_lab'"
    ):
        default_parameters("MastMechanism", undefined)
