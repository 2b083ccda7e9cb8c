"""Untrusted archives and files: size limits, references that leave their archive or folder,
errors that name what the user gave, and no temporary files left behind on any path."""

from __future__ import annotations

import json
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pytest
from test_batch import ssp as built_ssp  # noqa: F401 (the fixture: the default system's SSP, built from this tree)

import mast.core.ssp as ssp_module
from mast.core.ssp import SSPArchive, read_ssd, safe_extract
from mast.core.ssv import SSPFormatError
from mast.data.measured import MeasuredDataError, load

ROOT = Path(__file__).resolve().parents[1]
SSD = ROOT / "ssp" / "MAST.ssd"
RESOURCES = ROOT / "ssp" / "resources"


def _archive(path: Path, ssd_text: str, extra: dict | None = None) -> Path:
    """An .ssp with the default system's structure and parameter sets (no FMUs unless in ``extra``)."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("SystemStructure.ssd", ssd_text)
        for ssv in RESOURCES.glob("*.ssv"):
            if f"resources/{ssv.name}" not in (extra or {}):
                z.write(ssv, f"resources/{ssv.name}")
        for name, data in (extra or {}).items():
            z.writestr(name, data)
    return path


@pytest.fixture
def tmpdir_watch(tmp_path, monkeypatch) -> Path:
    """A fresh, empty temporary directory for everything this test (and its children) create."""
    fresh = tmp_path / "tmp"
    fresh.mkdir()
    monkeypatch.setenv("TMPDIR", str(fresh))
    monkeypatch.setattr(tempfile, "tempdir", str(fresh))
    return fresh


# -- archive size limits -------------------------------------------------------------------------
def test_a_zip_bomb_is_refused_before_it_is_written(tmp_path):
    bomb = _archive(tmp_path / "bomb.ssp", SSD.read_text(), {"resources/zeros.bin": bytes(8 << 20)})
    assert bomb.stat().st_size < 100_000  # 8 MiB of zeros compress about 1000 times
    with pytest.raises(SSPFormatError, match=r"bomb\.ssp: entry 'resources/zeros\.bin' is compressed \d+ times"):
        safe_extract(bomb, tmp_path / "out")
    assert not (tmp_path / "out" / "resources" / "zeros.bin").exists()


def test_total_and_entry_sizes_are_capped(tmp_path, monkeypatch):
    noise = np.random.default_rng(0).bytes(300_000)  # incompressible: only the size caps apply
    archive = _archive(tmp_path / "big.ssp", SSD.read_text(), {"a.bin": noise, "b.bin": noise})
    monkeypatch.setattr(ssp_module, "MAX_ARCHIVE_BYTES", 500_000)
    with pytest.raises(SSPFormatError, match=r"big\.ssp: expands to more than .*entry 'b\.bin'"):
        safe_extract(archive, tmp_path / "o1")
    monkeypatch.setattr(ssp_module, "MAX_ARCHIVE_BYTES", 1 << 30)
    monkeypatch.setattr(ssp_module, "MAX_ENTRY_BYTES", 200_000)
    with pytest.raises(SSPFormatError, match=r"big\.ssp: entry 'a\.bin' expands to"):
        safe_extract(archive, tmp_path / "o2")
    monkeypatch.setattr(ssp_module, "MAX_ENTRY_BYTES", 1 << 30)
    assert (safe_extract(archive, tmp_path / "o3") / "b.bin").read_bytes() == noise


# -- references that leave their archive or folder -----------------------------------------------
@pytest.mark.parametrize(
    "reference", ["/etc/passwd", "../../../etc/passwd", "resources/../../outside.ssv", "file:///etc/passwd"]
)
def test_ssd_sources_outside_the_archive_are_refused(tmp_path, reference):
    (tmp_path / "outside.ssv").write_text((RESOURCES / "mass_3prs.ssv").read_text())
    text = SSD.read_text().replace('source="resources/mass_3prs.ssv"', f'source="{reference}"')
    archive = _archive(tmp_path / "user.ssp", text)
    with pytest.raises(
        SSPFormatError,
        match=rf"user\.ssp \(entry SystemStructure\.ssd\): component 'mechanism' "
        rf"binds parameter set '{reference}' is not a relative path inside",
    ):
        SSPArchive(archive)
    fmu = SSD.read_text().replace('source="resources/MastMechanism.fmu"', f'source="{reference}"')
    with pytest.raises(SSPFormatError, match=r"component 'mechanism' source .* is not a relative path inside"):
        SSPArchive(_archive(tmp_path / "fmu.ssp", fmu))


@pytest.mark.parametrize(
    "attributes, message", [('prefix="m."', "prefix='m.'"), ('type="application/x-ssp-parameter-mapping"', "type=")]
)
def test_binding_features_the_reader_would_ignore_are_refused(tmp_path, attributes, message):
    text = SSD.read_text().replace(
        '<ssd:ParameterBinding source="resources/mass_3prs.ssv"/>',
        f'<ssd:ParameterBinding source="resources/mass_3prs.ssv" {attributes}/>',
    )
    with pytest.raises(SSPFormatError, match=rf"binding of 'mechanism' has {message}.*does not support"):
        SSPArchive(_archive(tmp_path / "user.ssp", text))
    nested = SSD.read_text().replace(
        'source="resources/MastMechanism.fmu" type="application/x-fmu-sharedlibrary"',
        'source="resources/MastMechanism.ssp" type="application/x-ssp-package"',
    )
    with pytest.raises(SSPFormatError, match=r"component 'mechanism' has type 'application/x-ssp-package': only FMUs"):
        SSPArchive(_archive(tmp_path / "nested.ssp", nested))


def test_a_measured_test_file_outside_the_data_folder_is_refused(tmp_path):
    folder = tmp_path / "data"
    folder.mkdir()
    (tmp_path / "secret.csv").write_text("time\n0\n")
    for reference in ("../secret.csv", "/etc/passwd", "../../../../etc/passwd"):
        (folder / "meta.json").write_text(
            json.dumps(
                {"format": "mast-measured-data", "version": 1, "units": {"time": "s"}, "tests": [{"file": reference}]}
            )
        )
        with pytest.raises(MeasuredDataError, match=r"meta\.json: tests\[0\] file .* is not a relative path inside"):
            load(folder)


# -- errors name the user's archive, not a deleted temporary folder ------------------------------
@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda s: s[: len(s) // 2], r"user\.ssp \(entry SystemStructure\.ssd\): cannot read the system structure"),
        (
            lambda s: s.replace(
                'endElement="mechanism" endConnector="rho_1"', 'endElement="mechanism" endConnector="rho_9"'
            ),
            r"user\.ssp \(entry SystemStructure\.ssd\): connection names input 'mechanism\.rho_9'",
        ),
        (
            lambda s: s.replace('startTime="0.0"', 'startTime="soon"'),
            r"user\.ssp \(entry SystemStructure\.ssd\): DefaultExperiment startTime='soon'",
        ),
    ],
)
def test_errors_inside_an_archive_name_the_archive_and_the_entry(tmp_path, tmpdir_watch, edit, message):
    archive = _archive(tmp_path / "user.ssp", edit(SSD.read_text()))
    with pytest.raises(SSPFormatError, match=message) as info:
        SSPArchive(archive)
    assert str(tmpdir_watch) not in str(info.value) and "mast_ssp_" not in str(info.value)
    assert not any(tmpdir_watch.iterdir())  # and the failed archive left nothing behind


def test_a_broken_parameter_set_inside_an_archive_names_the_archive_and_the_entry(tmp_path):
    archive = _archive(tmp_path / "user.ssp", SSD.read_text(), {"resources/mass_3prs.ssv": "<broken"})
    with pytest.raises(SSPFormatError, match=r"user\.ssp \(entry resources/mass_3prs\.ssv\): not well-formed XML"):
        SSPArchive(archive)


def test_a_source_folder_still_names_its_own_files(tmp_path):
    (tmp_path / "resources").symlink_to(RESOURCES)  # links inside the user's own folder are theirs
    (tmp_path / "x.ssd").write_text(SSD.read_text().replace('endConnector="rho_1"', 'endConnector="rho_9"', 1))
    with pytest.raises(SSPFormatError, match=rf"{tmp_path / 'x.ssd'}: connection names"):
        read_ssd(tmp_path / "x.ssd")


# -- nothing left behind --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def mechanism_fmu(tmp_path_factory) -> Path:
    from mast.core.build import FMUS, build_fmu

    spec = next(s for s in FMUS if s.model_identifier == "MastActuatorsOnly")
    return build_fmu(spec, tmp_path_factory.mktemp("fmus"))


def test_check_mechanism_leaves_no_temporary_files(mechanism_fmu, tmp_path, tmpdir_watch):
    from mast.hosts.conformance import check_mechanism

    assert all(c.passed for c in check_mechanism(mechanism_fmu, isolate=False))
    assert not any(tmpdir_watch.iterdir())
    broken = tmp_path / "broken.fmu"
    broken.write_bytes(mechanism_fmu.read_bytes()[:5000])
    with pytest.raises(SSPFormatError, match=r"broken\.fmu: not a readable zip"):
        check_mechanism(broken, isolate=False)
    assert not any(tmpdir_watch.iterdir())
    results = check_mechanism(broken)  # in the child process the CLI uses
    assert not results[0].passed and "broken.fmu" in results[0].detail
    assert not any(tmpdir_watch.iterdir()), list(tmpdir_watch.iterdir())


def test_a_run_leaves_no_temporary_files_after_success_and_after_failure(built_ssp, tmpdir_watch):
    from mast.core.components import ComponentError
    from mast.core.master import SimulationError
    from mast.core.motion import SineMotion
    from mast.core.run import simulate

    motion = SineMotion("z", 0.001, 5.0)
    assert len(simulate(built_ssp, motion, 0.005).time) > 1
    assert not any(tmpdir_watch.iterdir()), list(tmpdir_watch.iterdir())
    with pytest.raises((SimulationError, ComponentError), match="m_platform"):
        simulate(built_ssp, motion, 0.005, parameters={"mechanism": {"m_platform": -1.0}})
    assert not any(tmpdir_watch.iterdir()), list(tmpdir_watch.iterdir())


def test_a_batch_leaves_no_temporary_files_after_success_and_after_failure(built_ssp, tmp_path, tmpdir_watch):
    from mast.batch import run_batch

    config = {
        "ssp": str(built_ssp),
        "run": {"stop_time": 0.01, "record_step": 0.001},
        "cases": {
            "motion": {"axis": "z", "amplitude": 0.001, "frequency": 5},
            "list": [{"mechanism.m_platform": m} for m in (2.0, -1.0)],
        },
    }
    result = run_batch(config, tmp_path / "b", workers=1, progress=False, plots=False)
    assert (result.ok, result.failed) == (1, 1)
    assert not any(tmpdir_watch.iterdir()), list(tmpdir_watch.iterdir())


def _bomb_fmu(path: Path) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", bytes(8 << 20))
    return path


def test_a_zip_bomb_inside_an_ssp_or_given_as_an_fmu_is_named(tmp_path, tmpdir_watch):
    from mast.core.components import fmu_parameters
    from mast.core.motion import SineMotion
    from mast.core.run import simulate

    bomb = _bomb_fmu(tmp_path / "bomb.fmu").read_bytes()
    archive = _archive(
        tmp_path / "user.ssp",
        SSD.read_text(),
        {f"resources/{name}.fmu": bomb for name in ("MastController", "MastActuator", "MastMechanism")},
    )
    with pytest.raises(
        SSPFormatError,
        match=r"user\.ssp \(entry resources/Mast\w+\.fmu\): entry 'modelDescription\.xml' "
        r"is compressed \d+ times",
    ):
        simulate(archive, SineMotion("z", 0.001, 5.0), 0.01)
    assert not any(tmpdir_watch.iterdir())
    with pytest.raises(SSPFormatError, match=r"bomb\.fmu: entry 'modelDescription\.xml' is compressed"):
        fmu_parameters(tmp_path / "bomb.fmu")  # what `mast compare --mechanism X.fmu` reads first


def _escaping(source: Path, path: Path) -> Path:
    """A copy of the FMU ``source`` with one more entry, '../escape.txt', which would land beside its folder."""
    path.write_bytes(source.read_bytes())
    with zipfile.ZipFile(path, "a") as z:
        z.writestr("../escape.txt", "outside")
    return path


@pytest.mark.parametrize("kind", ["truncated", "escaping"])
def test_cli_check_mechanism_names_a_truncated_or_escaping_fmu_in_one_line(mechanism_fmu, tmp_path, capsys, kind):
    """Both printed the checking subprocess's traceback (exit 1); now one line naming the file, exit 2."""
    from mast.cli import main as cli_main

    if kind == "truncated":
        fmu = tmp_path / "cut.fmu"
        fmu.write_bytes(mechanism_fmu.read_bytes()[:5000])
        expected = f"error: {fmu}: not a readable zip archive (File is not a zip file)\n"
    else:
        fmu = _escaping(mechanism_fmu, tmp_path / "escape.fmu")
        expected = f"error: {fmu}: entry '../escape.txt' would be extracted outside the target folder\n"
    assert cli_main(["check-mechanism", str(mechanism_fmu), str(fmu)]) == 2
    out, err = capsys.readouterr()
    assert err == expected and out == ""  # checked before any FMU runs
    assert not (tmp_path.parent / "escape.txt").exists()


def test_validate_flags_an_fmu_or_ssp_entry_that_leaves_its_folder(mechanism_fmu, tmp_path, capsys):
    """`mast validate` said "no problems" for an FMU holding a '../' entry (fmpy does not look); it now names it as
    every reader of ours refuses it (core.ssp.check_archive), and an SSP's likewise, as a problem, not a traceback."""
    from mast.cli import main as cli_main

    build = tmp_path / "build"
    (build / "fmus").mkdir(parents=True)
    (build / "ssp").mkdir()
    (build / "fmus" / mechanism_fmu.name).write_bytes(mechanism_fmu.read_bytes())
    with zipfile.ZipFile(build / "ssp" / "S.ssp", "w") as z:
        z.writestr("SystemStructure.ssd", SSD.read_text())
    assert cli_main(["validate", "--build", str(build)]) == 0
    assert capsys.readouterr().out == "validation: no problems\n"
    _escaping(mechanism_fmu, build / "fmus" / "Escape.fmu")
    with zipfile.ZipFile(build / "ssp" / "E.ssp", "w") as z:
        z.writestr("SystemStructure.ssd", SSD.read_text())
        z.writestr("../escape.txt", "outside")
    assert cli_main(["validate", "--build", str(build)]) == 1
    assert capsys.readouterr().out.splitlines() == [
        "Escape.fmu: entry '../escape.txt' would be extracted outside the target folder",
        "E.ssp: entry '../escape.txt' would be extracted outside the target folder",
        "validation: 2 problem(s)",
    ]
