"""`mast reproduce`: every number the paper reports has a row, marked fit, reuse or prediction with the
tolerance it is judged by and its source; no prediction is a number a fit used; every figure is written."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import pytest
from docs_figures import figures

from mast.analyses import paper
from mast.analyses.identify import fit_targets
from mast.analyses.reproduce import plan, reproduce
from mast.core.ssv import parse_ssv

ROOT = Path(__file__).resolve().parents[1]
FIELDS = {
    "key",
    "quantity",
    "unit",
    "kind",
    "paper",
    "ours",
    "difference",
    "tolerance",
    "tolerance_band",
    "within_paper_deviation",
    "statement",
    "source",
    "note",
}


@pytest.fixture(scope="module")
def report(built, tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    # `mast reproduce` as the command runs it (without FMI, the full sweep): the figures docs/reproduction.md states
    summary = reproduce(str(built / "ssp" / "MAST.ssp"), out, workers=2, direct=True)
    return out, summary


def test_the_docs_state_this_runs_figures(report):
    """docs/reproduction.md's marked figures (the headline count, the 10 Hz positions) are this run's: a change
    that moves one fails here until the page says the new figure (`python docs/figures.py --source reproduce`)."""
    out, summary = report
    values = figures.reproduce_values(summary, json.loads((out / "paper_table.json").read_text()))
    problems = figures.check({"reproduce": values})
    assert not problems, "\n".join(problems)


def test_every_paper_number_has_a_marked_row(report):
    out, summary = report
    rows = json.loads((out / "paper_table.json").read_text())
    assert [r["key"] for r in rows] == [c.key for c in paper.CLAIMS]
    for r in rows:
        assert set(r) == FIELDS
        assert r["kind"] in ("fit", "reuse", "prediction")
        assert r["source"] and r["statement"]
        assert math.isfinite(r["ours"]), r["quantity"]
        assert r["difference"] == pytest.approx(r["ours"] - r["paper"])
        lo, hi = r["tolerance_band"]
        assert r["within_paper_deviation"] == (lo <= r["ours"] <= hi)
    assert not summary["failures"]
    assert summary["predictions"] >= 10


def test_no_prediction_is_a_number_a_fit_used(report):
    """The fit's own targets (identify.fit_targets, what `mast fit-gains` minimises) against the table's kinds."""
    out, _ = report
    rows = json.loads((out / "paper_table.json").read_text())
    used = set()
    for f, (mag, _ph) in fit_targets().items():
        used |= {
            paper.CLAIM[paper.position_key("magnitude", "z", f)].statement,
            paper.CLAIM[paper.position_key("phase", "z", f)].statement,
        }
        assert paper.CLAIM[paper.position_key("magnitude", "z", f)].value == mag
    for r in rows:
        if r["kind"] == "prediction":
            assert r["statement"] not in used, r["quantity"]
        if r["statement"] in used:
            assert r["kind"] in ("fit", "reuse"), r["quantity"]
    # the gains every run of the reproduction binds were fitted to these frequencies and nothing else
    fitted = parse_ssv(ROOT / "ssp" / "resources" / "controller_paper_reading_fit.ssv")
    assert f"z at {' and '.join(f'{f:g}' for f in fit_targets())} Hz only" in fitted["k_v"].source
    for case in (c for cases in plan("MAST.ssp").values() for c in cases):
        assert {g: case.parameters["controller"][g] for g in ("k_v", "k_p", "k_i")} == {
            g: fitted[g].value for g in ("k_v", "k_p", "k_i")
        }


def test_kinds_follow_the_fit_targets():
    """Fitting 10 Hz as well would turn every 10 Hz position row into a fit or a reuse."""
    with_10 = paper.FIT_KEYS + (paper.position_key("phase", "z", 10.0),)
    assert paper.kind(paper.CLAIM[paper.position_key("phase", "z", 10.0)], with_10) == "fit"
    assert paper.kind(paper.CLAIM[paper.position_key("phase", "psi", 10.0)], with_10) == "reuse"
    assert paper.kind(paper.CLAIM[paper.position_key("phase", "psi", 10.0)]) == "prediction"
    assert paper.kind(paper.CLAIM["bandwidth/z"], with_10) == "prediction"


def test_tolerance_is_the_papers_relative_deviation():
    phase = paper.CLAIM[paper.position_key("phase", "z", 10.0)]  # -103.7 deg: 13 % is 13.48 deg
    assert phase.within(-103.7 + 13.4) and not phase.within(-103.7 + 13.6)
    low = paper.CLAIM[paper.position_key("phase", "z", 0.4)]  # -6.3 deg: 13 % is 0.82 deg
    assert low.within(-7.1) and not low.within(-7.2)
    mag = paper.CLAIM[paper.position_key("magnitude", "z", 5.0)]
    assert mag.within(0.654 * 1.109) and not mag.within(0.654 * 1.111)
    assert not replace(mag, value=float("nan")).within(0.654)


def test_report_states_counts_limits_and_figures(report):
    out, summary = report
    text = (out / "report.md").read_text()
    assert f"**{summary['predictions_within']} of {summary['predictions']} predictions**" in text
    assert "## Where a test touches a limit" in text
    for name in (
        "fig7_bode.png",
        "fig8_10_frequency_response.png",
        "fig11_z_time.png",
        "fig12_psi_time.png",
        "fig13_theta_time.png",
    ):
        assert (out / name).stat().st_size > 20_000
        assert f"({name})" in text


def test_fits_hold_and_predictions_meet_the_goal(report):
    """The fitted rows meet the paper's deviation; at least 8 predictions do (issue 14's goal); the 0.4 Hz
    torque of the identified set is square-ish (friction)."""
    out, summary = report
    rows = {r["key"]: r for r in json.loads((out / "paper_table.json").read_text())}
    for key in paper.FIT_KEYS:
        assert rows[key]["within_paper_deviation"], key
    assert summary["fits_within"] == summary["fits"] == len(paper.FIT_KEYS)
    assert summary["predictions_within"] >= 8
    assert 0.2 < rows["torque/square_0.4Hz"]["ours"] < 0.4
    # Table 1's M* read as the carriage puts both resonances within 11 % (docs/reproduction.md)
    assert rows["tf2_resonance"]["within_paper_deviation"] and rows["fn_table1"]["within_paper_deviation"]


def test_runs_without_python_control(tmp_path):
    """python-control is a test extra only: the reproduction's modules and its Bode figure must not need it."""
    import subprocess
    import sys

    code = f"""
import sys
sys.modules["control"] = None  # any 'import control' now fails
from pathlib import Path
import mast.analyses.reproduce, mast.analyses.identify, mast.analyses.frequency, mast.core.run, mast.cli
from mast.core.ssv import parse_ssv
params = {{k: v.value for f in ("actuator_manufacturer", "transmission", "actuator_paper_reading")
          for k, v in parse_ssv(Path({str(ROOT)!r}) / "ssp" / "resources" / (f + ".ssv")).items()}}
print(mast.analyses.reproduce._plot_bode(params, Path({str(tmp_path)!r}), 2.27))
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "fig7_bode.png").stat().st_size > 20_000


def test_paper_table_is_strict_json_when_a_number_could_not_be_computed():
    """A failed run leaves NaN: written as null (strict JSON readers refuse NaN), never as a bare NaN."""
    from mast.analyses.reproduce import _strict

    row = {"ours": float("nan"), "tolerance_band": [0.5, float("inf")], "kind": "prediction"}
    assert json.loads(json.dumps(_strict(row), allow_nan=False)) == {
        "ours": None,
        "tolerance_band": [0.5, None],
        "kind": "prediction",
    }
