"""`mast animate`: the page draws the mechanism where the run put it, opens offline and animates; bad input
is refused by name with nothing written.

The runs are real co-simulations (the model objects on the FMUs' schedule, ``mast run --direct``) of two
designs, the paper's T layout with vertical guides and the inclined guides; the page's geometry is checked
against the recorded signals through formulas written here from docs/geometry.md (guide i's foot at
H (cos alpha_i, sin alpha_i, 0), its direction (-sin beta cos alpha_i, -sin beta sin alpha_i, cos beta)), not
through the description's code.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from docs_figures import figures
from message_tables import documented_messages, documented_mismatches

from fmus.mechanism import designs
from fmus.mechanism.engine import Description
from mast.analyses import animate
from mast.cli import main as cli_main
from mast.core.master import Result

ROOT = Path(__file__).resolve().parents[1]
DESIGNS = {
    "3PRS_T": ("MastMechanism", ROOT / "ssp" / "MAST.ssd"),
    "3PRS_inclined": ("Mast3PRSInclined", ROOT / "ssp" / "MAST_3PRS_inclined.ssd"),
}
#: the run: a psi sine of 4 deg at 2 Hz for 0.5 s (the peak tilt at 0.125 s)
MOTION = ["--motion", "psi", "--amplitude", "4", "--frequency", "2", "--stop-time", "0.5"]
#: the page writes coordinates to 10^-DECIMALS m: a point is off by at most half of that per axis
ROUNDING = 0.5 * 10.0**-animate.DECIMALS * math.sqrt(3)


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    """The run folder of each design (``mast run --direct``)."""
    from mast.core.build import FMUS, build_fmu, build_ssp

    out = tmp_path_factory.mktemp("animate")
    needed = {"MastActuator", "MastController"} | {fmu for fmu, _ in DESIGNS.values()}
    for spec in FMUS:
        if spec.model_identifier in needed:
            build_fmu(spec, out / "fmus")
    folders = {}
    for name, (_, ssd) in DESIGNS.items():
        ssp = build_ssp(ssd, out / "fmus", out / "ssp")
        folders[name] = out / name
        assert cli_main(["run", str(ssp), "--direct", *MOTION, "--out", str(folders[name])]) == 0
    return folders


@pytest.fixture(scope="module")
def pages(runs, tmp_path_factory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("pages")
    written = {}
    for name, folder in runs.items():
        written[name] = out / name / animate.PAGE
        assert cli_main(["animate", str(folder), "--out", str(out / name)]) == 0
    return written


def plotly_figure(html: str) -> tuple[list, list]:
    """(the first frame's traces, the frames) as the page's last script hands them to plotly.js (after the
    inlined library)."""
    decoder = json.JSONDecoder()
    start = html.rindex("Plotly.newPlot(")
    data, _ = decoder.raw_decode(html, html.index("[", html.index(",", start)))
    frames, _ = decoder.raw_decode(html, html.index("[", html.index("Plotly.addFrames(", start)))
    return data, frames


def external_resources(html: str) -> list[str]:
    """What the page's tags load from elsewhere (a script, style sheet, image or frame by address)."""
    from html.parser import HTMLParser

    found = []

    class Tags(HTMLParser):
        def handle_starttag(self, tag, attrs):
            found.extend(f"<{tag} {k}={v}>" for k, v in attrs if k in ("src", "href") and tag != "a")

    Tags().feed(html)
    return found


def xyz(trace: dict) -> list[np.ndarray]:
    """The polylines (or points) of a trace: runs of points between gaps."""
    lines, current = [], []
    for p in zip(trace["x"], trace["y"], trace["z"]):
        if p[0] is None:
            lines.append(np.array(current))
            current = []
        else:
            current.append(p)
    return lines + [np.array(current)]


def guides(params: dict) -> tuple[np.ndarray, np.ndarray]:
    """Feet and directions of the guides (docs/geometry.md; designs/3PRS_inclined.md)."""
    a = np.array([params[f"alpha_{i}"] for i in (1, 2, 3)])
    b, H = params.get("beta", 0.0), params["H"]
    feet = np.column_stack([H * np.cos(a), H * np.sin(a), np.zeros(3)])
    dirs = np.column_stack([-math.sin(b) * np.cos(a), -math.sin(b) * np.sin(a), np.full(3, math.cos(b))])
    return feet, dirs


@pytest.mark.parametrize("design", list(DESIGNS))
def test_page_draws_the_mechanism_where_the_run_put_it(runs, pages, design):
    html = pages[design].read_text(encoding="utf-8")
    assert external_resources(html) == []  # plotly.js is inlined: nothing fetched when opened
    first, frames = plotly_figure(html)
    names = [t["name"] for t in first]
    result = Result.read_csv(runs[design] / "results.csv")
    params = json.loads((runs[design] / "summary.json").read_text())["system"]["parameters"]["mechanism"]
    feet, dirs = guides(params)
    times = np.array([float(f["name"]) for f in frames])
    assert len(frames) == int(0.5 * animate.FPS) + 1
    np.testing.assert_allclose(np.diff(times), 1.0 / animate.FPS, atol=1e-9)
    psi_seen = []
    for frame in frames:
        traces = {names[i]: trace for i, trace in zip(frame["traces"], frame["data"])}
        k = int(np.argmin(abs(result.time - float(frame["name"]))))
        assert abs(result.time[k] - float(frame["name"])) < 1e-9
        carriages = xyz(traces["achieved: carriages"])[0]
        joints = xyz(traces["achieved: joints"])[0]
        # the mechanism's pose at t is the direct kinematics of the carriages at t - h (its inputs held over
        # the step: docs/animate.md); the first sample has no earlier one and is at rest
        rho = np.array([result[f"actuator_{i}.rho"][max(k - 1, 0)] for i in (1, 2, 3)])
        np.testing.assert_allclose(carriages, feet + rho[:, None] * dirs, rtol=0, atol=ROUNDING + 1e-9)
        legs = xyz(traces["achieved: links"])
        assert len(legs) == 3
        for i, leg in enumerate(legs):
            np.testing.assert_allclose(leg, [carriages[i], joints[i]], rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(joints - carriages, axis=1), params["L"], rtol=0, atol=2 * ROUNDING)
        centre = np.array(
            traces["achieved: plates"]["x"][:1]
            + traces["achieved: plates"]["y"][:1]
            + traces["achieved: plates"]["z"][:1]
        )
        recorded = np.array([result[f"mechanism.{c}"][k] for c in "xyz"])
        np.testing.assert_allclose(centre, recorded, rtol=0, atol=ROUNDING)
        np.testing.assert_allclose(np.linalg.norm(joints - centre, axis=1), params["r"], rtol=0, atol=2 * ROUNDING)
        # the ghost: the commanded pose (psi_cmd tilts the platform about x; z_cmd its centre's height)
        ghost_joints = xyz(traces["commanded: joints"])[0]
        ghost_centre = np.array([traces["commanded: plates"][a][0] for a in "xyz"])
        assert abs(ghost_centre[2] - result["z_cmd"][k]) <= ROUNDING
        ghost_carriages = xyz(traces["commanded: carriages"])[0]
        np.testing.assert_allclose(
            np.linalg.norm(ghost_joints - ghost_carriages, axis=1), params["L"], rtol=0, atol=2 * ROUNDING
        )
        psi_seen.append(result["mechanism.psi"][k])
    assert max(psi_seen) > math.radians(2.0)  # the frames span the motion


def test_frames_are_the_samples_nearest_each_frame_time():
    t = np.arange(0, 1.0005, 0.001)
    k = animate.frame_indices(t, 40.0)
    assert len(k) == 41 and np.all(np.abs(t[k] - np.arange(41) / 40.0) < 1e-9)
    uneven = np.array([0.0, 0.012, 0.03, 0.052, 0.1])  # 0.025 -> 0.03, 0.05 and 0.075 -> 0.052, 0.1
    assert list(animate.frame_indices(uneven, 40.0)) == [0, 2, 3, 4]


def test_a_part_is_checked_when_described():
    from fmus.mechanism.engine import Part

    with pytest.raises(ValueError, match="part kind 'wing'"):
        Part("wing", "platform", [(0.0, 0.0, 0.0)])
    with pytest.raises(ValueError, match="a guide is a part of the base"):
        Part("guide", None, [(0.0, 0.0, 0.0), (0.0, 0.0, 1.0)])
    with pytest.raises(ValueError, match="points must be finite"):
        Part("link", "leg_1", [(0.0, 0.0, math.nan), (0.26, 0.0, 0.0)])


def test_the_docs_state_this_pages_size(runs):
    """docs/animate.md's frames and sizes are those of the page of ANIMATE_RUN on the system the runs above were made
    with (`python docs/figures.py --source animate` writes them)."""
    problems = figures.check({"animate": figures.source_animate(runs["3PRS_T"].parent / "ssp" / "MAST.ssp")})
    assert not problems, "\n".join(problems)


# ----------------------------------------------------------------------------- bad input
def copy_run(runs, tmp_path) -> Path:
    folder = tmp_path / "run"
    shutil.copytree(runs["3PRS_T"], folder)
    return folder


def refused(capsys, folder: Path, out: Path) -> str:
    """The error of `mast animate FOLDER --out OUT` (exit 2), which wrote no page and no temporary file."""
    assert cli_main(["animate", str(folder), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert not (out / animate.PAGE).exists()
    assert not [p for p in out.parent.rglob("*.tmp")]
    return err


def test_out_is_a_folder_the_former_page_name_is_refused_naming_the_new_form(runs, tmp_path, capsys):
    """`--out` names a folder in every subcommand: a page's name (animate's former meaning) is refused before anything
    runs, with the form to use; without --out the page goes into the run folder."""
    folder = copy_run(runs, tmp_path)
    with pytest.raises(SystemExit) as stop:
        cli_main(["animate", str(folder), "--out", str(tmp_path / "page.html")])
    assert stop.value.code == 2
    assert f"mast animate RUN_DIR --out DIR writes DIR/{animate.PAGE}" in capsys.readouterr().err
    assert not (tmp_path / "page.html").exists()
    assert cli_main(["animate", str(folder)]) == 0
    assert "Plotly.newPlot(" in (folder / animate.PAGE).read_text()


def test_a_folder_without_results_is_refused_by_name(runs, tmp_path, capsys):
    folder = copy_run(runs, tmp_path)
    (folder / "results.csv").unlink()
    assert "no results.csv" in refused(capsys, folder, tmp_path / "pages")


def test_a_missing_pose_column_is_refused_by_name(runs, tmp_path, capsys):
    folder = copy_run(runs, tmp_path)
    result = Result.read_csv(folder / "results.csv")
    del result.signals["mechanism.theta"]
    result.write_csv(folder / "results.csv")
    assert "no column 'mechanism.theta'" in refused(capsys, folder, tmp_path / "pages")


def test_a_mechanism_without_geometry_is_refused_by_name(runs, tmp_path, capsys):
    folder = copy_run(runs, tmp_path)
    summary = json.loads((folder / "summary.json").read_text())
    mechanism = summary["system"]["parameters"]["mechanism"]
    del mechanism["L"]
    (folder / "summary.json").write_text(json.dumps(summary))
    assert "'L'" in refused(capsys, folder, tmp_path / "pages")
    mechanism["L"], mechanism["attached"] = 0.26, 0  # the actuators_only design: no mechanism attached
    (folder / "summary.json").write_text(json.dumps(summary))
    assert "not attached (parameter 'attached' = 0" in refused(capsys, folder, tmp_path / "pages")
    del summary["system"]  # a run folder from before the record
    (folder / "summary.json").write_text(json.dumps(summary))
    assert "no 'system.parameters'" in refused(capsys, folder, tmp_path / "pages")


def _summary(change):
    """A change of a copied run folder's summary.json: ``change(summary)`` edits the parsed document."""

    def make(folder: Path) -> Path:
        summary = json.loads((folder / "summary.json").read_text())
        change(summary)
        (folder / "summary.json").write_text(json.dumps(summary))
        return folder

    return make


def _results(change):
    """A change of a copied run folder's results.csv: ``change(result)`` edits the signals."""

    def make(folder: Path) -> Path:
        result = Result.read_csv(folder / "results.csv")
        change(result)
        result.write_csv(folder / "results.csv")
        return folder

    return make


def _write(name: str, text: str):
    def make(folder: Path) -> Path:
        (folder / name).write_text(text)
        return folder

    return make


def _remove(name: str):
    def make(folder: Path) -> Path:
        (folder / name).unlink()
        return folder

    return make


def _mechanism(name: str, value):
    return _summary(lambda s: s["system"]["parameters"]["mechanism"].__setitem__(name, value))


def _tilted(column: str):
    """``column`` at 1.5 rad (86 deg, beyond the 3PRS's admissible 60 deg tilt) from the 5th sample on."""
    return _results(lambda r: r.signals[column].__setitem__(slice(5, None), 1.5))


class Unsketched(Description):
    """A description written in Python that gives no drawing (``Description.sketch``'s default)."""

    name = "unsketched"


#: docs/animate.md's "Bad input" table: input -> how each of its quoted messages is made from a copy of a run folder
BAD_INPUT = {
    "a path that is not a folder": (lambda folder: folder / "nowhere",),
    "a folder without `results.csv` or `summary.json`": (_remove("results.csv"), _remove("summary.json")),
    "a `results.csv` that is not a run's table: text for a number, a header and no rows, times that do not increase": (
        _write("results.csv", "time,mechanism.z\n0.0,x\n"),
        _write("results.csv", "time,mechanism.z\n"),
        _write("results.csv", "time,mechanism.z\n0.0,0.3\n0.0,0.3\n"),
    ),
    "a `summary.json` that is not a JSON object": (_write("summary.json", "{"), _write("summary.json", "[1]")),
    "a run folder from before `system` was recorded": (_summary(lambda s: s.pop("system")),),
    "a run without a mechanism component": (_summary(lambda s: s["system"]["parameters"].pop("mechanism")),),
    "a design without geometry: the mechanism not attached (`actuators_only`, `attached` = 0)": (
        _mechanism("attached", 0),
    ),
    "a geometry parameter missing, not a number, or out of its range": (
        _summary(lambda s: s["system"]["parameters"]["mechanism"].pop("L")),
        _mechanism("L", "long"),
        _mechanism("L", -0.26),
    ),
    "a description without a drawing (a description written in Python whose `sketch` is empty)": (
        _mechanism("kinematics", "unsketched"),
    ),
    "a pose column missing": (
        _results(lambda r: r.signals.pop("mechanism.theta")),
        _results(lambda r: r.signals.pop("theta_cmd")),
    ),
    "a pose the mechanism cannot assemble (a recorded tilt beyond the admissible 60 deg)": (
        _tilted("mechanism.psi"),
        _tilted("psi_cmd"),
    ),
}


def test_the_documented_bad_input_messages_are_the_codes(runs, tmp_path, monkeypatch):
    """Every row of docs/animate.md's "Bad input" table is made here, and the page quotes what the code says for it,
    message by message (``...`` for any text, DIR for the folder)."""
    monkeypatch.setitem(designs.KINEMATICS, "unsketched", lambda params, masses=True: Unsketched())
    rows = documented_messages(ROOT / "docs" / "animate.md", "## Bad input")
    assert set(rows) == set(BAD_INPUT), set(rows) ^ set(BAD_INPUT)
    actual = {}
    for k, (problem, makers) in enumerate(BAD_INPUT.items()):
        actual[problem] = []
        for j, make in enumerate(makers):
            folder = tmp_path / f"{k}_{j}"
            shutil.copytree(runs["3PRS_T"], folder)
            with pytest.raises(animate.AnimateError) as error:
                animate.replay(make(folder))
            actual[problem].append(str(error.value))
    problems = documented_mismatches(rows, actual)
    assert not problems, "docs/animate.md's Bad input table (update the page):\n" + "\n".join(problems)


def test_a_failed_write_leaves_the_old_page_and_no_temporary_file(runs, tmp_path, monkeypatch):
    import mast.core.atomic as atomic

    out = tmp_path / "page.html"
    out.write_text("the old page")

    def refuse(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(atomic.os, "replace", refuse)
    with pytest.raises(OSError, match="disk full"):
        animate.write(runs["3PRS_T"], out)
    assert out.read_text() == "the old page"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["page.html"]


# ----------------------------------------------------------------------------- in a browser
def rgb(hex_colour: str) -> np.ndarray:
    return np.array([int(hex_colour[k : k + 2], 16) for k in (1, 3, 5)]) / 255.0


#: the drawing's colours of the legs and the carriages
LINK, CARRIAGE = rgb(animate.COLOURS["link"]), rgb(animate.COLOURS["carriage"])


def screenshot(page: Path, at: float, into: Path) -> np.ndarray:
    """The page opened at the frame nearest ``at`` s in headless Chromium, as RGB in [0, 1]."""
    import matplotlib.image

    return matplotlib.image.imread(str(animate.screenshot(page, into / f"t{at:g}.png", at)))[:, :, :3]


def near(image: np.ndarray, colour: np.ndarray) -> np.ndarray:
    return np.abs(image - colour).max(axis=2) < 0.06


@pytest.mark.skipif(
    animate.chromium() is None,
    reason="Chromium is not installed (Debian: apt-get install chromium); .ci/run installs it where it can",
)
def test_the_page_draws_and_animates_the_mechanism_in_a_browser(pages, tmp_path):
    rest = screenshot(pages["3PRS_T"], 0.0, tmp_path)
    tilted = screenshot(pages["3PRS_T"], 0.125, tmp_path)
    for image in (rest, tilted):
        assert near(image, LINK).sum() > 300, "the legs are not drawn"
        assert near(image, CARRIAGE).sum() > 100, "the carriages are not drawn"
    moved = near(rest, LINK) ^ near(tilted, LINK)
    assert moved.sum() > 100, "the legs are drawn at the same place at 0 s and at the peak tilt"
