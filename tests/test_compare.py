"""`mast compare`: a design swapped in from its FMU is the system a user would write by hand,
and a (small) comparison writes its table, data and plots."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest
from docs_figures import figures

from mast.analyses.compare import compare, fmu_parameters, swapped_ssd
from mast.cli import main as cli_main
from mast.core.designs import DESIGNS
from mast.core.ssp import read_ssd, validate_ssd_schema

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> Path:
    from mast.core.build import FMUS, build_fmu

    out = tmp_path_factory.mktemp("compare_fmus")
    for spec in FMUS:
        if spec.model_identifier in (
            "MastActuator",
            "MastController",
            "MastMechanism",
            "MastActuatorsOnly",
            "Mast3PRSInclined",
        ):
            build_fmu(spec, out)
    return out


def test_swapping_an_fmu_gives_the_design_system(fmus, tmp_path):
    """The automatic swap binds what ssp/MAST_<design>.ssd binds, for every component."""
    for d in DESIGNS[1:]:
        fmu = fmus / f"{d.model_identifier}.fmu"
        if not fmu.exists():
            continue
        text = swapped_ssd((ROOT / "ssp" / "MAST.ssd").read_text(), fmu.name, fmu_parameters(fmu), d.name)
        (tmp_path / "resources").mkdir(exist_ok=True)
        for ssv in (ROOT / "ssp" / "resources").glob("*.ssv"):
            link = tmp_path / "resources" / ssv.name
            if not link.exists():
                link.symlink_to(ssv)
        (tmp_path / "swapped.ssd").write_text(text)
        assert validate_ssd_schema(tmp_path / "swapped.ssd") == []
        swapped, reference = read_ssd(tmp_path / "swapped.ssd"), read_ssd(d.ssd)
        for name, comp in reference.components.items():
            assert swapped.components[name].parameters == pytest.approx(comp.parameters), (d.name, name)
            assert Path(swapped.components[name].source).name == Path(comp.source).name


def test_compare_writes_table_data_and_plots(fmus, tmp_path):
    """docs/figures.py's short variant (MastMechanism and MastActuatorsOnly, z at 2 and 8 Hz), whose figures
    docs/designs/README.md states."""
    out = tmp_path / "cmp"
    data = figures.run_designs_short(fmus, out)
    assert [c["label"] for c in data["designs"]] == ["MastMechanism", "MastActuatorsOnly"]
    values = figures.designs_values(data)
    problems = figures.check({"designs_short": values})
    assert not problems, "\n".join(problems)
    # what the page's words say of these figures (paper Fig. 10): the rigid-body mechanism does not lower the bandwidth,
    # and both designs' drives hold the 2 Hz sine and fail at 8 Hz
    assert values["fig10"]["rise_pct"] > 0, values
    assert all(
        values[d]["sizing_holds_up_to_Hz"] == 2.0 and values[d]["sizing_margin_pct"] < 0
        for d in figures.DESIGNS_SHORT[0]
    )
    for name in (
        "comparison.csv",
        "runs.csv",
        "comparison.json",
        "comparison.md",
        "bode.png",
        "bandwidth.png",
        "torque.png",
        "tracking.png",
        "parasitic.png",
        "systems/MastMechanism.ssp",
    ):
        assert (out / name).stat().st_size > 100, name
    rows = list(csv.DictReader(open(out / "comparison.csv")))
    assert [(r["design"], r["motion"]) for r in rows] == [("MastMechanism", "z"), ("MastActuatorsOnly", "z")]
    for r in rows:
        assert r["failed"] == "0"
        assert 2.0 < float(r["bandwidth_Hz"]) < 8.0  # magnitude falls through -3 dB in between
        assert 0.0 < float(r["torque_rms_Nm"]) < float(r["torque_peak_Nm"]) < 0.31
        assert 0.0 < float(r["tracking_peak"]) < 2 * 0.005
        # the workspace beside them: the same kinematics for both (the actuators alone report the 3PRS's poses)
        assert float(r["workspace_m_deg2"]) == pytest.approx(float(rows[0]["workspace_m_deg2"]))
        assert float(r["workspace_m_deg2"]) > 100.0
        assert float(r["margin_min"]) >= 0.05 and float(r["margin_home"]) == pytest.approx(0.5412, abs=1e-3)
    assert len(data["runs"]) == 4 and data["wall_time_s"] > 0
    fig10 = data["fig10"]
    assert set(fig10["actuators_alone"]) == {"MastActuatorsOnly"} and set(fig10["with_mechanism"]) == {"MastMechanism"}
    assert "Fig. 10" in (out / "comparison.md").read_text()
    # the mechanism loads the drives: more torque than the actuators alone at 2 Hz
    runs = {(r["design"], r["frequency_Hz"]): r for r in data["runs"]}
    assert runs[("MastMechanism", 2.0)]["torque_rms_Nm"] > runs[("MastActuatorsOnly", 2.0)]["torque_rms_Nm"]


def test_cli_compare(fmus, tmp_path):
    out = tmp_path / "cli"
    code = cli_main(
        [
            "compare",
            "--mechanism",
            str(fmus / "Mast3PRSInclined.fmu"),
            "--out",
            str(out),
            "--quick",
            "--frequencies",
            "3",
            "--motions",
            "theta",
            "--workers",
            "1",
            "--fmus",
            str(fmus),
        ]
    )
    assert code == 0
    row = next(csv.DictReader(open(out / "comparison.csv")))
    assert row["design"] == "Mast3PRSInclined" and row["motion"] == "theta"
    assert (
        float(row["workspace_m_deg2"]) > 100.0 and "Workspace (`mast workspace`" in (out / "comparison.md").read_text()
    )
    assert float(row["parasitic_x_m"]) >= 0.0 and math.isfinite(float(row["torque_peak_Nm"]))
    assert cli_main(["compare", "--mechanism", str(tmp_path / "none.fmu"), "--out", str(out)]) == 2


def test_swapping_into_a_system_without_bindings(fmus, tmp_path):
    """A base system that binds nothing: the swap creates the bindings the design needs."""
    import re

    base = re.sub(
        r"\s*<ssd:ParameterBindings>.*?</ssd:ParameterBindings>",
        "",
        (ROOT / "ssp" / "MAST.ssd").read_text(),
        flags=re.S,
    )
    fmu = fmus / "Mast3PRSInclined.fmu"
    (tmp_path / "bare.ssd").write_text(swapped_ssd(base, fmu.name, fmu_parameters(fmu), "bare"))
    assert validate_ssd_schema(tmp_path / "bare.ssd") == []
    system = read_ssd(tmp_path / "bare.ssd")
    assert system.components["controller"].parameters["beta"] == pytest.approx(math.radians(15.0))
    assert system.components["actuator_3"].parameters == {"g_guide": pytest.approx(9.81 * math.cos(math.radians(15)))}
    assert system.components["mechanism"].parameters["H"] == 0.55


def test_a_missing_design_is_refused_before_anything_is_written(tmp_path):
    """The items are checked first: a missing FMU after a valid one leaves no --out folder (not even empty)."""
    out = tmp_path / "new"
    with pytest.raises(FileNotFoundError, match="mechanism .*missing.fmu: no such file"):
        compare([ROOT / "ssp" / "MAST.ssd", tmp_path / "missing.fmu"], out)
    with pytest.raises(ValueError, match=r"expected an \.fmu"):
        compare([ROOT / "README.md"], out)
    assert not out.exists()
    assert cli_main(["compare", "--mechanism", str(tmp_path / "missing.fmu"), "--out", str(out)]) != 0
    assert not out.exists()
