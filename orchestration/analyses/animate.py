"""`mast animate`: a run replayed in 3-D, one self-contained HTML page (docs/animate.md).

A run folder of ``mast run`` holds ``results.csv`` (time and every signal) and ``summary.json``, whose
``system`` records the SSP and, per component, the parameter values the master set. The mechanism's
description is rebuilt from its parameters (``fmus.mechanism.designs.describe``: the same code as the
mechanism FMU's) and drawn from its own ``sketch`` (``fmus.mechanism.engine.Part``: base, guides, carriages,
legs, joints, platform, each in the frame of its body): at each shown time the description's ``evaluate``
places every body at the recorded pose (``mechanism.<coordinate>``), and a translucent ghost at the commanded
pose (``<coordinate>_cmd``). Nothing in this module knows the 3PRS: any description with a sketch is drawn.

The page is a plotly figure (plotly.js inlined: it opens offline, no script fetched) with one animation frame
per 1/``fps`` s of simulated time (the recorded sample nearest to it), play/pause buttons and a time slider;
``PAGE.html#t=1.25`` opens it at the frame nearest 1.25 s. Coordinates are written to 1 micrometre
(``DECIMALS``). The guides are drawn from the base to the top of their carriage's stroke (``rho_max`` of
``actuator_<joint>``, else the highest position the carriage reaches in the run).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Optional, Sequence, Union

import numpy as np

from fmus.common.parameters import ParameterError
from fmus.mechanism.designs import describe
from fmus.mechanism.engine import Description, Part
from fmus.mechanism.kinematics import KinematicsError

from ..core.atomic import atomic_write
from ..core.master import Result

#: frames per second of simulated time (the recorded sample nearest to each frame time is shown)
FPS = 40.0
#: the page `mast animate` writes into its --out folder
PAGE = "motion.html"
#: decimals of the coordinates [m] written in the page (1 micrometre)
DECIMALS = 6
#: the component whose outputs are the pose and whose parameters describe the mechanism
MECHANISM = "mechanism"
#: the component driving joint coordinate j (0-based), whose stroke bounds the drawn guide
ACTUATOR = "actuator_{}"
#: colours of the drawing (achieved pose), and the ghost's (commanded pose)
COLOURS = {
    "base": "#9e9e9e",
    "guide": "#424242",
    "plate": "#1f77b4",
    "link": "#d62728",
    "carriage": "#ff7f0e",
    "joint": "#2ca02c",
    "ghost": "#7b1fa2",
}
GHOST_OPACITY = 0.3


class AnimateError(ValueError):
    """A run folder that cannot be replayed: names the file, column or parameter missing."""


@dataclass
class Replay:
    """What the page shows: ``times`` [s] of the frames, per frame the world points [m] of every part of
    ``parts`` at the achieved and at the commanded pose (``achieved[k][p]``: (n, 3) array), and per guide its
    drawn ends."""

    label: str
    parts: tuple[Part, ...]
    times: np.ndarray
    achieved: list[list[np.ndarray]]
    commanded: list[list[np.ndarray]]
    guides: list[np.ndarray]


# ----------------------------------------------------------------------------- the run folder
def load(run_dir: Union[str, Path]) -> tuple[Result, dict]:
    """(signals of ``results.csv``, ``summary.json``) of a run folder; AnimateError naming what is missing."""
    folder = Path(run_dir)
    if not folder.is_dir():
        raise AnimateError(f"{folder}: not a folder (expected a `mast run` output folder)")
    csv_path, summary_path = folder / "results.csv", folder / "summary.json"
    for path in (csv_path, summary_path):
        if not path.is_file():
            raise AnimateError(
                f"{folder}: no {path.name} (expected a `mast run` output folder: results.csv and summary.json)"
            )
    try:
        result = Result.read_csv(csv_path)
    except (ValueError, IndexError, UnicodeDecodeError) as exc:
        raise AnimateError(f"{csv_path}: not a results table (header time,SIGNAL,... then numbers): {exc}") from None
    if len(result.time) == 0:
        raise AnimateError(f"{csv_path}: no rows (the run recorded nothing)")
    if not np.all(np.diff(result.time) > 0):
        raise AnimateError(f"{csv_path}: the column 'time' does not increase from row to row")
    try:
        summary = json.loads(summary_path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise AnimateError(f"{summary_path}: not JSON: {exc}") from None
    if not isinstance(summary, dict):
        raise AnimateError(f"{summary_path}: expected a JSON object")
    return result, summary


def mechanism_parameters(summary: Mapping, where: str) -> dict:
    """The mechanism's parameter values a run recorded (``summary.json``: system.parameters.mechanism)."""
    system = summary.get("system")
    parameters = system.get("parameters") if isinstance(system, Mapping) else None
    if not isinstance(parameters, Mapping):
        raise AnimateError(
            f"{where}: no 'system.parameters' (the parameter values of the run's components, "
            "written by `mast run` since it records them): run it again to replay it"
        )
    mech = parameters.get(MECHANISM)
    if not isinstance(mech, Mapping):
        raise AnimateError(
            f"{where}: the run has no component '{MECHANISM}' (components: "
            f"{', '.join(parameters) or 'none'}): no mechanism to draw"
        )
    return dict(mech)


def description_of(params: Mapping, where: str) -> Description:
    """The kinematic description of the mechanism's parameters, with its sketch; AnimateError naming what is
    missing (a geometry parameter, a detached mechanism, a description without a drawing)."""
    if params.get("attached", 1) == 0:
        raise AnimateError(
            f"{where}: the mechanism is not attached (parameter 'attached' = 0: the actuators "
            "alone, paper Fig. 10): no mechanism geometry to draw"
        )
    try:
        desc = describe(params, MECHANISM, masses=False)
    except KeyError as exc:
        raise AnimateError(f"{where}: the mechanism's parameters have no {exc} (its geometry)") from None
    except (ParameterError, KinematicsError, ValueError, TypeError) as exc:
        raise AnimateError(f"{where}: the mechanism's geometry: {exc}") from None
    if not desc.sketch():
        raise AnimateError(f"{where}: the {desc.name} description has no drawing (Description.sketch)")
    return desc


def _column(result: Result, name: str, what: str, where: str) -> np.ndarray:
    if name not in result.signals:
        raise AnimateError(f"{where}: no column {name!r} ({what})")
    return result[name]


def frame_indices(time_s: np.ndarray, fps: float) -> np.ndarray:
    """Indices of the recorded samples nearest to t0, t0 + 1/fps, ... up to the last time (each shown once)."""
    if not (math.isfinite(fps) and fps > 0):
        raise AnimateError(f"fps {fps!r}: expected a positive, finite number of frames per second")
    t0, t1 = float(time_s[0]), float(time_s[-1])
    wanted = t0 + np.arange(int(math.floor((t1 - t0) * fps + 1e-9)) + 1) / fps
    last = len(time_s) - 1
    right = np.clip(np.searchsorted(time_s, wanted), 0, last)
    left = np.clip(right - 1, 0, last)
    nearest = np.where(np.abs(time_s[left] - wanted) <= np.abs(time_s[right] - wanted), left, right)
    return np.unique(nearest)


def place(desc: Description, parts: Sequence[Part], q: Sequence[float]) -> tuple[list[np.ndarray], list[float]]:
    """World points [m] of every part at pose ``q`` (the description's ``evaluate``: each body's frame) and the
    joint coordinates rho [m] there."""
    ev = desc.evaluate([float(v) for v in q])
    frames = {
        body.name: (np.asarray(origin, dtype=float), np.asarray(R, dtype=float))
        for body, (origin, R) in zip(desc.bodies, ev.frames)
    }
    placed = []
    for part in parts:
        points = np.asarray(part.points, dtype=float)
        if part.body is not None:
            origin, R = frames[part.body]
            points = origin + points @ R.T
        placed.append(points)
    return placed, [float(r) for r in ev.rho]


def replay(run_dir: Union[str, Path], fps: float = FPS) -> Replay:
    """The frames of a run folder (module docstring)."""
    result, summary = load(run_dir)
    where = str(Path(run_dir) / "summary.json")
    params = mechanism_parameters(summary, where)
    desc = description_of(params, where)
    parts = desc.sketch()
    where_csv = str(Path(run_dir) / "results.csv")
    achieved_q = np.column_stack(
        [_column(result, f"{MECHANISM}.{c}", "the achieved pose", where_csv) for c in desc.coordinates]
    )
    commanded_q = np.column_stack(
        [_column(result, f"{c}_cmd", "the commanded pose", where_csv) for c in desc.coordinates]
    )
    index = frame_indices(result.time, fps)
    achieved, commanded, top = [], [], np.full(len(desc.joints), -math.inf)
    for k in index:
        for q, into, what in ((achieved_q[k], achieved, "achieved"), (commanded_q[k], commanded, "commanded")):
            try:
                placed, rho = place(desc, parts, q)
            except KinematicsError as exc:
                raise AnimateError(
                    f"{where_csv}: the {what} pose at t = {result.time[k]:g} s cannot be drawn: {exc}"
                ) from None
            into.append(placed)
            top = np.maximum(top, rho)
    strokes = summary["system"]["parameters"]
    guides = []
    for part in parts:
        if part.kind == "guide":
            actuator = strokes.get(ACTUATOR.format(part.joint + 1), {})
            lo = min(0.0, float(actuator.get("rho_min", 0.0)))
            hi = float(actuator.get("rho_max", top[part.joint]))
            base, unit = np.asarray(part.points[0]), np.asarray(part.points[1]) - np.asarray(part.points[0])
            guides.append(np.array([base + lo * unit, base + hi * unit]))
    ssp = summary["system"].get("ssp")
    label = f"{Path(ssp).stem if ssp else Path(run_dir).name}: {desc.name}"
    motion = summary.get("motion")
    if isinstance(motion, Mapping) and {"axis", "amplitude", "frequency_Hz"} <= set(motion):
        amplitude = (
            f"{motion['amplitude']:.4g} m" if motion["axis"] == "z" else f"{math.degrees(motion['amplitude']):.4g} deg"
        )
        label += f", {motion['axis']} sine {amplitude} at {motion['frequency_Hz']:g} Hz"
    if summary.get("error"):
        label += f" (the run stopped at {result.time[-1]:g} s: {summary['error']})"
    return Replay(label, parts, result.time[index], achieved, commanded, guides)


# ----------------------------------------------------------------------------- the figure
def _polylines(arrays: Sequence[np.ndarray], closed: bool = False) -> dict:
    """x, y, z lists of polylines separated by gaps (None), coordinates rounded to DECIMALS."""
    xyz: list[list] = [[], [], []]
    for points in arrays:
        rows = np.vstack([points, points[:1]]) if closed else points
        for axis in range(3):
            xyz[axis] += [round(float(v), DECIMALS) for v in rows[:, axis]] + [None]
    return dict(zip("xyz", (values[:-1] for values in xyz)))


def _points(arrays: Sequence[np.ndarray]) -> dict:
    stacked = np.vstack(arrays)
    return {axis: [round(float(v), DECIMALS) for v in stacked[:, k]] for k, axis in enumerate("xyz")}


def _mesh(outlines: Sequence[np.ndarray]) -> dict:
    """Every closed outline filled by a fan of triangles around its centroid (convex outlines)."""
    vertices, faces = [], []
    for outline in outlines:
        start = sum(len(v) for v in vertices)
        vertices.append(np.vstack([outline.mean(axis=0), outline]))
        n = len(outline)
        faces += [(start, start + 1 + k, start + 1 + (k + 1) % n) for k in range(n)]
    mesh = _points(vertices)
    mesh.update(i=[f[0] for f in faces], j=[f[1] for f in faces], k=[f[2] for f in faces])
    return mesh


def _moving(parts: Sequence[Part], placed: Sequence[np.ndarray], ghost: bool) -> list[dict]:
    """The moving traces of one pose: plates, links, carriages, joints (ghost: translucent, one colour)."""

    def of(kind):
        return [p for part, p in zip(parts, placed) if part.kind == kind and part.body is not None]

    colour = (lambda kind: COLOURS["ghost"]) if ghost else (lambda kind: COLOURS[kind])
    opacity = GHOST_OPACITY if ghost else 1.0
    who = "commanded" if ghost else "achieved"
    traces = []
    if of("plate"):
        traces.append(
            dict(
                type="mesh3d",
                name=f"{who}: plates",
                color=colour("plate"),
                opacity=opacity * 0.6,
                flatshading=True,
                hoverinfo="skip",
                showlegend=True,
                **_mesh(of("plate")),
            )
        )
    if of("link"):
        traces.append(
            dict(
                type="scatter3d",
                mode="lines",
                name=f"{who}: links",
                opacity=opacity,
                line=dict(color=colour("link"), width=9),
                **_polylines(of("link")),
            )
        )
    for kind, symbol, size in (("carriage", "square", 9), ("joint", "circle", 5)):
        if of(kind):
            traces.append(
                dict(
                    type="scatter3d",
                    mode="markers",
                    name=f"{who}: {kind}s",
                    opacity=opacity,
                    marker=dict(color=colour(kind), symbol=symbol, size=size),
                    **_points(of(kind)),
                )
            )
    return traces


def _static(replay: Replay) -> list[dict]:
    plates = [np.asarray(p.points) for p in replay.parts if p.kind == "plate" and p.body is None]
    traces = []
    if plates:
        traces.append(
            dict(
                type="mesh3d",
                name="base",
                color=COLOURS["base"],
                opacity=0.5,
                flatshading=True,
                hoverinfo="skip",
                showlegend=True,
                **_mesh(plates),
            )
        )
    if replay.guides:
        traces.append(
            dict(
                type="scatter3d",
                mode="lines",
                name="guides",
                line=dict(color=COLOURS["guide"], width=4),
                **_polylines(replay.guides),
            )
        )
    return traces


def _frame_name(t: float) -> str:
    return f"{t:.3f}"


def figure(replay: Replay, fps: float = FPS) -> dict:
    """The plotly figure (a dict: data, layout, frames) of a replay."""
    static = _static(replay)
    frames = []
    for k, t in enumerate(replay.times):
        data = _moving(replay.parts, replay.achieved[k], False) + _moving(replay.parts, replay.commanded[k], True)
        frames.append(dict(name=_frame_name(t), data=data, traces=list(range(len(static), len(static) + len(data)))))
    drawn = [k for k, part in enumerate(replay.parts) if part.body is not None or part.kind == "plate"]
    everything = np.vstack([pose[k] for pose in replay.achieved + replay.commanded for k in drawn] + replay.guides)
    lo, hi = everything.min(axis=0), everything.max(axis=0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2 * 1.1
    span = np.maximum(hi - lo, 1e-3) * 1.1 / 2
    axes = {
        f"{a}axis": dict(range=[centre[k] - span[k], centre[k] + span[k]], title=f"{a} [m]", autorange=False)
        for k, a in enumerate("xyz")
    }
    instant = dict(mode="immediate", frame=dict(duration=0, redraw=True), transition=dict(duration=0))
    slider = dict(
        active=0,
        x=0.08,
        len=0.9,
        y=0.02,
        pad=dict(t=40),
        currentvalue=dict(prefix="t = ", suffix=" s", font=dict(size=16)),
        font=dict(color="rgba(0,0,0,0)"),
        ticklen=0,
        minorticklen=0,
        steps=[dict(method="animate", label=f["name"], args=[[f["name"]], instant]) for f in frames],
    )
    play = dict(
        frame=dict(duration=1000.0 / fps, redraw=True), transition=dict(duration=0), fromcurrent=True, mode="immediate"
    )
    menu = dict(
        type="buttons",
        direction="left",
        x=0.0,
        y=0.02,
        xanchor="left",
        yanchor="top",
        pad=dict(t=40, r=10),
        showactive=False,
        buttons=[
            dict(label="play", method="animate", args=[None, play]),
            dict(label="pause", method="animate", args=[[None], instant]),
        ],
    )
    layout = dict(
        title=dict(text=f"{replay.label}; ghost: the commanded pose", x=0.02),
        height=660,
        margin=dict(l=0, r=0, t=50, b=90),
        showlegend=True,
        legend=dict(x=0.99, xanchor="right", y=0.98),
        scene=dict(
            aspectmode="manual",
            aspectratio={a: float(span[k] / half) for k, a in enumerate("xyz")},
            camera=dict(eye=dict(x=1.05, y=-1.15, z=0.45), center=dict(x=0, y=0, z=-0.1)),
            **axes,
        ),
        updatemenus=[menu],
        sliders=[slider],
    )
    return dict(data=static + frames[0]["data"], layout=layout, frames=frames)


def _frame_hook(times: np.ndarray) -> str:
    """Page script: ``#t=SECONDS`` in the address shows the frame nearest that time."""
    names = json.dumps([_frame_name(t) for t in times])
    return (
        "var gd = document.getElementById('{plot_id}'); var names = " + names + ";"
        "var m = /[#&]t=([-+0-9.eE]+)/.exec(window.location.hash); if (m) { var t = parseFloat(m[1]);"
        "var best = 0; for (var k = 1; k < names.length; k++) {"
        " if (Math.abs(parseFloat(names[k]) - t) < Math.abs(parseFloat(names[best]) - t)) best = k; }"
        "return Plotly.animate(gd, [names[best]], {mode: 'immediate', frame: {duration: 0, redraw: true},"
        " transition: {duration: 0}}); }"
    )


def page(replay: Replay, fps: float = FPS) -> str:
    """The self-contained HTML page (plotly.js inlined) of a replay."""
    import plotly.io as pio

    fig = figure(replay, fps)
    return pio.to_html(
        fig,
        include_plotlyjs=True,
        full_html=True,
        auto_play=False,
        validate=False,
        post_script=_frame_hook(replay.times),
        config={"displaylogo": False},
        div_id="mast-animate",
    )


def write(run_dir: Union[str, Path], out: Union[str, Path], fps: float = FPS) -> dict:
    """``out`` (an HTML page) from the run folder ``run_dir``, written all or nothing: frames, bytes, seconds."""
    start = time.perf_counter()
    out = Path(out)
    if out.is_dir():
        raise AnimateError(f"{out}: a folder; expected the page's file name")
    rep = replay(run_dir, fps)
    text = page(rep, fps).encode("utf-8")
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(out, text)
    return {
        "out": str(out),
        "frames": len(rep.times),
        "fps": fps,
        "bytes": len(text),
        "simulated_s": float(rep.times[-1] - rep.times[0]),
        "seconds": time.perf_counter() - start,
    }


# ----------------------------------------------------------------------------- a picture of the page
#: headless Chromium, offline and with a software WebGL (no GPU): what tests/test_animate.py and
#: docs/figures/make_animate.py open the page with
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--enable-unsafe-swiftshader",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--virtual-time-budget=10000",
)


def chromium() -> Optional[str]:
    """The Chromium executable on the PATH (Debian's ``chromium``), or None."""
    import shutil

    return shutil.which("chromium") or shutil.which("chromium-browser")


def screenshot(
    page_path: Union[str, Path], png: Union[str, Path], at: Optional[float] = None, size: tuple[int, int] = (1000, 760)
) -> Path:
    """A PNG of the page (at the frame nearest ``at`` s: ``#t=``) by headless Chromium, with a fresh profile
    removed after; RuntimeError when Chromium is absent or writes no picture."""
    import subprocess
    import tempfile

    browser = chromium()
    if browser is None:
        raise RuntimeError("Chromium is not installed (Debian: apt-get install chromium)")
    png = Path(png)
    address = Path(page_path).resolve().as_uri() + ("" if at is None else f"#t={at:g}")
    with tempfile.TemporaryDirectory(prefix="mast_chromium_") as profile:
        run = subprocess.run(
            [
                browser,
                *CHROMIUM_FLAGS,
                f"--user-data-dir={profile}",
                f"--window-size={size[0]},{size[1]}",
                f"--screenshot={png}",
                address,
            ],
            capture_output=True,
            text=True,
            timeout=300,
        )
    if not png.is_file():
        raise RuntimeError(f"Chromium wrote no screenshot of {address} (exit {run.returncode}): {run.stderr[-2000:]}")
    return png


__all__ = [
    "AnimateError",
    "CHROMIUM_FLAGS",
    "FPS",
    "Replay",
    "chromium",
    "figure",
    "frame_indices",
    "load",
    "page",
    "place",
    "replay",
    "screenshot",
    "write",
]
