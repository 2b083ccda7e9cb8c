"""`mast compare`: run one test set on several mechanism designs, or several controllers; write a table and plots.

A design is given as a mechanism FMU (or as a whole system, .ssp/.ssd). For an FMU the
system is the base system (``ssp/MAST.ssd``) with the mechanism swapped, exactly as a user
would swap it by hand in the SSP (docs/interfaces.md, "Writing a mechanism FMU"):

- the ``mechanism`` component's source is the FMU, bound to the FMU's own default parameters
  (the design is what the FMU says it is);
- the controller's kinematic model (``kinematics``, H, r, L, alpha_1..3, beta: the FMU's
  values of the geometry parameters it declares, those of its description: ``kinematic_names``) is
  bound after the controller's sets;
- the actuators' gravity along the guides is g cos(beta) when the FMU declares ``beta``.

A mechanism FMU of another mechanism with a system of its own (``mast.core.designs.MECHANISMS``: the
3-RPS's Mast3RPS.fmu) is swapped into that system instead (``own_system``: its controller and
actuators are built for it).

The test set is pure sine motions on every coordinate of the designs' mechanisms (their topology:
for the 3PRS z, psi and theta) at several frequencies around the home pose (paper section 4.1;
amplitudes of ``paper.AMPLITUDE``, ``amplitude`` for a coordinate the paper does not move). For every design and
motion: the closed-loop -3 dB bandwidth, peak and RMS motor torque, peak tracking error and
parasitic motion amplitudes; and beside them each design's workspace (``mast workspace`` of its
system: volume, smallest singularity margin inside, margin at home, distance from home to the
nearest singularity). Outputs in DIR: comparison.csv (one row per design and motion),
runs.csv (one row per sine test), comparison.json (everything), comparison.md (the table),
bode.png, bandwidth.png, torque.png, tracking.png, parasitic.png, and systems/*.ssp (the
systems that were run, for `mast run`).

A mechanism may also be given by the name of its shipped description file (``workspace.described``: for example
``3RPS`` for ``fmus/mechanism/descriptions/3RPS.toml``) when it has no system yet: it is not run, and its workspace
(its own strokes and home), margins and static forces at rest stand beside the designs' (comparison.csv rows with
no motion, comparison.json "descriptions", comparison.md's workspace and static-force tables).

``--controller`` compares controllers the same way (``compare(controllers=...)``): a
controller is named (joint, workspace, feedforward, computed_torque: its system
``ssp/MAST_<name>.ssd``), given as a controller FMU (swapped into the base system's
``controller`` component with the FMU's own defaults) or as a whole system. Every test runs
twice: as designed, and with a payload of ``payload`` kg on the platform that the
controllers do not know (the mechanism's ``m_payload``; their models keep the nominal
sets): the robustness to a model mismatch. The table gains the payload's effect on
bandwidth and tracking error, and each motion gets its figure motion_<axis>.png (magnitude,
tracking error, peak torque against frequency, nominal and with the payload).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import re
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Mapping, Optional, Sequence, Union

from fmus.common.parameters import Value
from fmus.mechanism.designs import KINEMATIC_PARAMETERS_NAMES, KINEMATICS, kinematic_names
from fmus.mechanism.topology import POSE, POSE_UNITS, Coordinate

from ..core import ssd, ssv
from ..core.build import default_build_dir
from ..core.components import fmu_parameters, fmu_variables
from ..core.motion import system_axes
from ..core.specimen import PAYLOAD_NAMES, Specimen
from ..core.ssp import SSPArchive, mechanism_parameters
from . import paper, sizing
from .frequency import SineCase, SineResult, bandwidth, run_cases
from .workspace import STEP_TILT_DEG, STEP_Z, described, unit_text

REPO = Path(__file__).resolve().parents[2]
BASE_SSD = REPO / "ssp" / "MAST.ssd"
FMU_DIR = default_build_dir() / "fmus"
#: payload [kg] the controllers do not know, for the robustness runs (assumed: about 1.5 times the
#: 2.06 kg platform, a heavy specimen; it must stay within the drives' current at the test amplitudes)
PAYLOAD_MISMATCH_KG = 3.0
#: geometry parameters the controller's kinematic model takes from the mechanism FMU
KINEMATIC_NAMES = KINEMATIC_PARAMETERS_NAMES
#: grid of the designs' workspaces (``mast workspace``'s default) and the coarse one of --quick
WORKSPACE_GRID = (STEP_Z, math.radians(STEP_TILT_DEG))
WORKSPACE_GRID_QUICK = (0.025, math.radians(4.0))


@dataclass(frozen=True)
class TestSet:
    """Sine motions: for each axis, each frequency [Hz], amplitude in m (x, y, z) or rad (the angles). No
    ``axes``: every coordinate of the designs' mechanisms (``compare``; the 3PRS: z, psi, theta)."""

    __test__ = False  # not a pytest test class

    axes: tuple[str, ...] = ()
    frequencies: tuple[float, ...] = (0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0)
    amplitudes: Mapping[str, float] = field(default_factory=lambda: dict(paper.AMPLITUDE))


def amplitude(axis: str) -> float:
    """The test amplitude of a coordinate: the paper's (``paper.AMPLITUDE``: z 5 mm, psi and theta 0.8 deg), and
    for one the paper does not move (x, y, phi) assumed the paper's of the same unit (z's for a length, psi's for
    an angle): a small motion well inside any workspace the MAST's strokes give."""
    if axis in paper.AMPLITUDE:
        return paper.AMPLITUDE[axis]
    return paper.AMPLITUDE["psi" if Coordinate(axis).angular else "z"]


def for_axes(test_set: TestSet, axes: Sequence[str]) -> TestSet:
    """``test_set`` with the coordinates ``axes`` (of the designs' mechanisms) when it names none, and an amplitude
    (``amplitude``) for every axis it moves that it gives none."""
    moved = tuple(test_set.axes) or tuple(axes)
    extra = {a: amplitude(a) for a in moved if a in POSE and a not in test_set.amplitudes}
    return TestSet(moved, test_set.frequencies, {**test_set.amplitudes, **extra})


#: the default set (every coordinate): about 1 minute per 3PRS design on 2 cores
DEFAULT = TestSet()
#: the smallest useful set (tests, smoke runs): z only, around the bandwidth
QUICK = TestSet(axes=("z",), frequencies=(1.0, 4.0, 8.0))


@dataclass
class Candidate:
    """One design to compare: a label, the system to run, where it came from."""

    label: str
    ssp: str
    source: str
    parameters: dict = field(default_factory=dict)  # the mechanism FMU's defaults (empty for a system)
    payload_kg: float = 0.0  # a payload on the platform the controller does not know
    nominal: str = ""  # label of the same system without it (payload runs)
    workspace: Optional[dict] = None  # the design's `mast workspace` summary (designs only)

    def overrides(self, parameters: Optional[Mapping[str, Mapping[str, Value]]]) -> Optional[dict]:
        """The caller's overrides, plus the unknown payload on the mechanism: a point mass at P, bolted to the
        specimen the overrides put there (``--specimen``), if any."""
        if not self.payload_kg:
            return dict(parameters) if parameters else None
        out = {k: dict(v) for k, v in (parameters or {}).items()}
        mechanism = out.setdefault("mechanism", {})
        if any(name in mechanism for name in PAYLOAD_NAMES):
            carried = Specimen.from_parameters(mechanism)
            mechanism.update(carried.combined(Specimen(self.payload_kg)).parameters())
        else:
            mechanism["m_payload"] = self.payload_kg
        return out


@dataclass
class Comparison:
    """What ``compare`` found; ``summary`` rows are what comparison.csv holds."""

    candidates: list[Candidate]
    test_set: TestSet
    results: dict  # (label, axis) -> list[SineResult], in test-set frequency order
    summary: list[dict]
    wall_time_s: float
    files: list[Path]
    kind: str = "design"  # what the candidates are: "design" (mechanisms) or "controller"
    parasitic: dict = field(default_factory=dict)  # label -> the pose components its mechanism does not command
    #: mechanisms given by their description alone (``workspace.described``): not run, their workspace beside the
    #: designs' ({"label", "source", "workspace", "note"})
    descriptions: list = field(default_factory=list)
    #: label -> the coordinates of its mechanism that another candidate's lacks (the hexapod's x, y, phi beside the
    #: 3-DOF designs'): not in the common test set, listed beside it
    extra: dict = field(default_factory=dict)

    def row(self, label: str, axis: str) -> dict:
        for r in self.summary:
            if r["design"] == label and r["motion"] == axis:
                return r
        raise KeyError((label, axis))


# ----------------------------------------------------------------------------- systems
def swapped_ssd(
    base_text: str,
    fmu_name: str,
    params: Mapping[str, Value],
    label: str,
    component_name: str = "mechanism",
    condensed: bool = True,
) -> str:
    """The base system's text with its ``mechanism`` (or ``controller``) swapped for the FMU (module docstring);
    ``condensed=False``: a mechanism FMU without the condensed coupling's variables, wired for the explicit
    exchange (``explicit_wiring``)."""
    document = ssd.read(base_text.encode("utf-8"), "the base system")
    try:
        swapped = document.system.component(component_name)
    except KeyError:
        raise ValueError(f"the base system has no component named '{component_name}' to swap") from None
    swapped.source = f"resources/{fmu_name}"  # its own defaults replace whatever the base bound
    swapped.bindings = [_inline(params, f"default of {fmu_name}")]
    for comp in document.system.elements if component_name == "mechanism" else ():
        extra, why = {}, ""
        if comp.name == "controller":
            extra = {k: params[k] for k in kinematic_names(params) if k in params}
            why = f"the controller's kinematic model: the geometry of {fmu_name}"
        elif Path(comp.source).stem == "MastActuator" and "beta" in params and "g" in params:
            extra = {"g_guide": float(params["g"]) * math.cos(float(params["beta"]))}
            why = f"gravity along the guides of {fmu_name}: g cos(beta)"
        if extra:
            comp.bindings.append(_inline(extra, why))  # bound last: it overrides
    if not condensed:
        explicit_wiring(document.system)
    document.name = f"MAST_{label}"
    return document.to_bytes().decode("utf-8")


#: the mechanism's connectors of the condensed coupling (docs/coupling.md), by the prefix of their names
CONDENSED = ("F_drive_", "F_drive_dot_", "F_drive_ddot_", "m_drive_", "Fc_", "Mc_")


def explicit_wiring(system: ssd.System) -> None:
    """Wire ``system``'s mechanism for the explicit exchange (docs/interfaces.md, a mechanism FMU of another tool):
    its F_k to the actuators' F, none of the condensed coupling's connectors or connections."""
    mechanism = system.component("mechanism")
    mechanism.connectors = [c for c in mechanism.connectors if not c.name.startswith(CONDENSED)]
    wired = []
    for c in system.connections:
        if c.start_element == "mechanism" and c.start_connector.startswith("Fc_"):
            wired.append(dataclasses.replace(c, start_connector="F_" + c.start_connector[3:]))
        elif not (
            (c.end_element == "mechanism" and c.end_connector.startswith(CONDENSED))
            or (c.start_element == "mechanism" and c.start_connector.startswith(CONDENSED))
        ):
            wired.append(c)
    system.connections = wired


def own_system(fmu: Path, params: Mapping[str, Value]) -> Optional[Path]:
    """The system of another mechanism (``designs.MECHANISMS``, ssp/MAST_<design>.ssd) that the mechanism FMU ``fmu``
    (its default ``params``) belongs in: its controller and actuators are that mechanism's, so the FMU is swapped
    into it rather than into the 3PRS's base system; None for a 3PRS."""
    from ..core.designs import MECHANISMS

    for d in MECHANISMS:
        if fmu.stem == d.model_identifier or params.get("kinematics") == d.name:
            return d.ssd
    return None


def _inline(values: Mapping[str, Value], why: str) -> ssd.ParameterBinding:
    """An inline binding of ``values``, each described by ``why``."""
    return ssd.ParameterBinding(values=ssv.parameter_set("design", values, descriptions=dict.fromkeys(values, why)))


def _label(path: Path, taken: set) -> str:
    base = re.sub(r"[^A-Za-z0-9_]+", "_", path.stem) or "design"
    label, k = base, 2
    while label in taken:
        label, k = f"{base}_{k}", k + 1
    taken.add(label)
    return label


def prepare(
    mechanisms: Sequence[Union[str, Path]],
    out: Union[str, Path],
    base_ssd: Union[str, Path] = BASE_SSD,
    fmu_dir: Union[str, Path] = FMU_DIR,
    component: str = "mechanism",
) -> list[Candidate]:
    """One runnable system per design: an FMU is swapped into ``base_ssd`` (packed into
    out/systems/<label>.ssp with the FMUs of ``fmu_dir`` for the other components); an .ssp or
    .ssd is used as it is. ``component="controller"``: the items are controllers, and a
    controller's name (``controllers.CONTROLLERS``) stands for its system ssp/MAST_<name>.ssd."""
    from ..core.build import build_ssp
    from ..core.controllers import CONTROLLERS

    out, base_ssd, fmu_dir = Path(out), Path(base_ssd), Path(fmu_dir)
    candidates: list[Candidate] = []
    taken: set = set()
    base_text = base_ssd.read_text(encoding="utf-8")
    named = {c.name: c for c in CONTROLLERS} if component == "controller" else {}
    for item in mechanisms:  # every item checked before anything is written
        if str(item) not in named:
            path = Path(item)
            if not path.exists():
                known = f" or a controller name ({', '.join(named)})" if named else ""
                if component == "mechanism":
                    known = f" or a mechanism description's name ({', '.join(k for k in KINEMATICS if described(k))})"
                raise FileNotFoundError(f"{component} {path}: no such file{known}")
            if path.suffix not in (".fmu", ".ssp", ".ssd"):
                raise ValueError(
                    f"{component} {path}: expected an .fmu (a {component} to swap in) or an .ssp/.ssd (a system)"
                )
    for item in mechanisms:
        if str(item) in named:
            label = _label(Path(str(item)), taken)
            built = build_ssp(named[str(item)].ssd, fmu_dir, out / "systems")
            ssp = built.replace(built.with_name(f"{label}.ssp"))
            candidates.append(Candidate(label, str(ssp), str(named[str(item)].ssd)))
            continue
        path = Path(item)
        label = _label(path, taken)
        if path.suffix in (".ssp", ".ssd"):
            with SSPArchive(path) as archive:  # the mechanism's bound parameters (attached, geometry ...)
                comp = archive.system.components.get("mechanism")
                params = mechanism_parameters(comp) if comp is not None and component == "mechanism" else {}
            candidates.append(Candidate(label, str(path), str(path), params))
            continue
        params = fmu_parameters(path)
        own = own_system(path, params) if component == "mechanism" and base_ssd == BASE_SSD else None
        with tempfile.TemporaryDirectory(prefix="mast_compare_") as tmp:
            tmp = Path(tmp)
            shutil.copytree(base_ssd.parent / "resources", tmp / "resources", ignore=shutil.ignore_patterns("*.fmu"))
            fmus = tmp / "fmus"
            fmus.mkdir()
            for fmu in fmu_dir.glob("*.fmu"):
                (fmus / fmu.name).symlink_to(fmu.resolve())
            target = fmus / path.name
            if target.exists() or target.is_symlink():
                target.unlink()
            target.symlink_to(path.resolve())
            ssd = tmp / f"{label}.ssd"
            text = own.read_text(encoding="utf-8") if own is not None else base_text
            condensed = component != "mechanism" or "Fc_1" in fmu_variables(path)
            ssd.write_text(swapped_ssd(text, path.name, params, label, component, condensed), encoding="utf-8")
            ssp = build_ssp(ssd, fmus, out / "systems")
        candidates.append(Candidate(label, str(ssp), str(path), params if component == "mechanism" else {}))
    return candidates


# ----------------------------------------------------------------------------- the comparison
def _finite(x: Optional[float]) -> Optional[float]:
    return x if x is not None and math.isfinite(x) else None


def summarize(
    label: str,
    axis: str,
    amplitude: float,
    results: Sequence[SineResult],
    payload_kg: float = 0.0,
    parasitic: Sequence[str] = ("x", "y", "phi"),
) -> dict:
    """A comparison row: one design's tests of one motion; ``parasitic``: the pose components its mechanism does
    not command (``parasitic_of``; the 3PRS's by default), their amplitudes as ``parasitic_<c>_<unit>``."""
    ok = [r for r in results if not r.error]
    freqs = [r.frequency for r in ok]
    bw = bandwidth(freqs, [r.ratio for r in ok]) if len(ok) > 1 else None
    peak = max((max(r.torque_peak) for r in ok), default=math.nan)
    rms = max((max(r.torque_rms) for r in ok), default=math.nan)
    track = max((r.tracking_peak for r in ok), default=math.nan)
    current = max((max(r.current_peak) for r in ok if r.current_peak), default=math.nan)
    par = {k: max((r.parasitic.get(k, math.nan) for r in ok), default=math.nan) for k in parasitic}
    return {
        "design": label,
        "motion": axis,
        "amplitude": amplitude,
        "payload_kg": payload_kg,
        "bandwidth_Hz": bw,
        "bandwidth_note": (
            ""
            if bw is not None
            else (f"above {max(freqs):g} Hz" if ok and abs(ok[-1].ratio) >= 10 ** (-3 / 20) else "not found")
        ),
        "torque_peak_Nm": _finite(peak),
        "torque_rms_Nm": _finite(rms),
        "current_peak_A": _finite(current),
        "tracking_peak": _finite(track),
        "tracking_peak_rel": _finite(track / amplitude) if amplitude else None,
        "tracking_peak_f_min": _finite(ok[0].tracking_peak) if ok else None,  # at the lowest frequency: quasi-static
        **{parasitic_column(k): _finite(v) for k, v in par.items()},
        "tests": len(results),
        "failed": len(results) - len(ok),
        "errors": sorted({r.error for r in results if r.error}),
    }


def compare(
    mechanisms: Sequence[Union[str, Path]] = (),
    out: Union[str, Path] = "comparison",
    test_set: Optional[TestSet] = None,
    quick: bool = False,
    workers: Optional[int] = None,
    direct: bool = False,
    parameters: Optional[Mapping[str, Mapping[str, Value]]] = None,
    base_ssd: Union[str, Path] = BASE_SSD,
    fmu_dir: Union[str, Path] = FMU_DIR,
    plots: bool = True,
    progress: Optional[Callable[[int, int], None]] = None,
    controllers: Sequence[Union[str, Path]] = (),
    payload: float = PAYLOAD_MISMATCH_KG,
    workspace_grid: Optional[tuple[float, float]] = WORKSPACE_GRID,
) -> Comparison:
    """Run the test set (``QUICK`` if ``quick``, else ``DEFAULT``) on every design, or on every controller
    (``controllers``, each also with an unknown ``payload`` [kg] unless it is 0); write DIR (module docstring).

    ``parameters``: overrides applied to every design (``{"actuator_1": {"tau_c": 0.07}}``);
    ``direct``: run the model objects without FMI (only for this project's FMUs);
    ``workspace_grid``: (step in z [m], step in tilt [rad]) of each design's workspace (``mast workspace``;
    None: none).
    """
    if bool(mechanisms) == bool(controllers):
        raise ValueError("compare: give either mechanisms or controllers")
    if not (math.isfinite(payload) and payload >= 0.0):
        raise ValueError(f"compare: payload = {payload!r} kg: expected a finite mass >= 0")
    t0 = time.perf_counter()
    out = Path(out)
    test_set = test_set or (QUICK if quick else DEFAULT)
    for axis in test_set.axes:
        if axis not in POSE:
            raise ValueError(f"test set: motion {axis!r}: expected a pose component ({', '.join(POSE)})")
    kind = "controller" if controllers else "design"
    # a mechanism named by its description alone (no system to run): its workspace, margins and static forces
    alone = [str(m) for m in mechanisms if not Path(m).exists() and described(str(m))]
    runnable = [m for m in mechanisms if str(m) not in alone]
    # out is made once the candidates are known: a missing FMU leaves no empty folder behind
    candidates = prepare(controllers or runnable, out, base_ssd, fmu_dir, "controller" if controllers else "mechanism")
    axes_of = {}
    for c in candidates:  # every motion a coordinate of every candidate's mechanism (its topology)
        with SSPArchive(c.ssp) as archive:
            axes_of[c.label] = axes = system_axes(archive.system, c.overrides(parameters))
        test_set = for_axes(test_set, axes)
        for axis in test_set.axes:
            if axis not in axes:
                raise ValueError(
                    f"test set: motion {axis!r}: {c.label} has no such coordinate; its mechanism's "
                    f"coordinates are {', '.join(axes)}"
                )
    out.mkdir(parents=True, exist_ok=True)
    if controllers and payload:
        candidates += [
            Candidate(f"{c.label} +{payload:g} kg", c.ssp, c.source, c.parameters, payload, c.label) for c in candidates
        ]
        axes_of.update({c.label: axes_of[c.nominal] for c in candidates if c.nominal})
    cases, keys = [], []
    for c in candidates:
        for axis in test_set.axes:
            for f in test_set.frequencies:
                cases.append(
                    SineCase(
                        c.ssp,
                        axis,
                        test_set.amplitudes[axis],
                        f,
                        c.overrides(parameters),
                        direct,
                        sizing_signals(len(axes_of[c.label])),
                        label=c.label,
                    )
                )
                keys.append((c.label, axis))
    results_flat = run_cases(cases, workers=workers, progress=progress)
    if kind == "design" and workspace_grid is not None:
        common = common_axes(axes_of.values())
        for c in candidates:
            c.workspace = design_workspace(c, workspace_grid, common if len(axes_of[c.label]) > 3 else None)
    results: dict = {}
    for key, res in zip(keys, results_flat):
        results.setdefault(key, []).append(res)
    summary = [
        summarize(
            c.label,
            axis,
            test_set.amplitudes[axis],
            results[(c.label, axis)],
            c.payload_kg,
            parasitic_of(axes_of[c.label]),
        )
        | workspace_columns(c.workspace)
        | sizing_columns(c, results[(c.label, axis)], parameters)
        for c in candidates
        for axis in test_set.axes
    ]
    comp = Comparison(
        candidates,
        test_set,
        results,
        summary,
        0.0,
        [],
        kind,
        {label: parasitic_of(axes) for label, axes in axes_of.items()},
        [description_only(name, workspace_grid) for name in alone],
        {label: extra for label, axes in axes_of.items() if (extra := extra_motions(axes, axes_of.values()))},
    )
    comp.files = write(comp, out, plots=plots)
    comp.wall_time_s = time.perf_counter() - t0
    meta = json.loads((out / "comparison.json").read_text())
    meta["wall_time_s"] = round(comp.wall_time_s, 2)
    (out / "comparison.json").write_text(json.dumps(meta, indent=2))
    return comp


def common_axes(axes: Iterable[Sequence[str]]) -> tuple[str, ...]:
    """The coordinates every candidate's mechanism has (``axes``: each one's), in the pose's order."""
    sets = [set(a) for a in axes]
    return tuple(c for c in POSE if sets and all(c in s for s in sets))


def extra_motions(axes: Sequence[str], every: Iterable[Sequence[str]]) -> tuple[str, ...]:
    """The coordinates of ``axes`` not common to ``every`` candidate's (``common_axes``)."""
    common = common_axes(every)
    return tuple(c for c in axes if c not in common)


def sizing_signals(n: int) -> tuple[str, ...]:
    """What the drive sizing of each test of a system with ``n`` drives needs, kept in its steady state."""
    return tuple(f"actuator_{k}.{s}" for k in range(1, n + 1) for s in sizing.SIGNALS) + tuple(
        f"controller.i_cmd_{k}" for k in range(1, n + 1)
    )


def parasitic_of(axes: Sequence[str]) -> tuple[str, ...]:
    """The pose components a mechanism with the coordinates ``axes`` does not command (the 3PRS: x, y, phi)."""
    return tuple(c for c in POSE if c not in axes)


def parasitic_column(c: str) -> str:
    """The column of a parasitic pose component's amplitude: parasitic_<c>_<unit> (parasitic_x_m, parasitic_phi_rad)."""
    return f"parasitic_{c}_{POSE_UNITS[c]}"


def sizing_columns(
    c: Candidate, results: Sequence[SineResult], parameters: Optional[Mapping[str, Mapping[str, Value]]]
) -> dict:
    """The drives of a design over its tests of one motion (``mast sizing`` of each test's steady cycle, run
    continuously): the verdict, the limiting item (drive, item and test) and its margin, the highest test
    frequency up to which no test fails; ``sizing_note`` says why there is none."""
    from ..core.ssp import read_ssd

    try:
        if Path(c.ssp).suffix == ".ssd":
            drive_set = sizing.drives(read_ssd(c.ssp), c.overrides(parameters))
        else:
            with SSPArchive(c.ssp) as archive:
                drive_set = sizing.drives(archive.system, c.overrides(parameters))
    except ValueError as err:
        return {"sizing_verdict": None, "sizing_note": str(err)}
    verdicts = []
    for r in results:
        if r.error or "time" not in r.signals:
            continue
        v = sizing.verdict(sizing.size_signals(drive_set, r.signals["time"], r.signals, r.frequency))
        verdicts.append((v, r.frequency))
    if not verdicts:
        return {"sizing_verdict": None, "sizing_note": "no test to size"}
    order = {"pass": 0, "at limit": 1, "fail": 2}
    worst, f = min(verdicts, key=lambda vf: vf[0]["limiting"]["margin"])
    lim = worst["limiting"]
    held = None  # the highest test frequency up to which no test fails
    for v, freq in sorted(verdicts, key=lambda vf: vf[1]):
        if v["verdict"] == "fail":
            break
        held = freq
    return {
        "sizing_verdict": max((v["verdict"] for v, _ in verdicts), key=order.get),
        "sizing_limiting": f"{lim['drive']} {lim['component']} {lim['item']} at {f:g} Hz",
        "sizing_margin": lim["margin"],
        "sizing_holds_up_to_Hz": held,
        "sizing_note": "",
    }


def design_workspace(c: Candidate, grid: tuple[float, float], sweep: Optional[Sequence[str]] = None) -> dict:
    """The `mast workspace` summary of a design's system (its mechanism and its actuators' strokes) over the
    coordinates ``sweep`` (None: every coordinate of its mechanism; a hexapod's: the ones common to the designs
    compared, the others held at home), or {"error": why} when the system does not define them."""
    from fmus.mechanism.kinematics import KinematicsError

    from . import workspace

    try:
        return workspace.summarize(workspace.compute(workspace.machine(c.ssp), grid[0], grid[1], sweep=sweep))
    except KeyError as exc:
        return {
            "error": f"no workspace: the mechanism's parameters do not describe its mechanism (no "
            f"{exc.args[0]!r}; `mast workspace` needs its geometry, for a 3PRS H, r, L, alpha_1..3: "
            "docs/workspace.md)"
        }
    except (ValueError, KinematicsError) as exc:
        return {"error": f"no workspace: {exc}"}


#: why a mechanism given by its description alone is not run
NOT_RUN = (
    "not run: a description alone has no system (its mechanism FMU and an SSD with one actuator per drive; "
    "docs/designs/3rps.md)"
)


def description_only(name: str, grid: Optional[tuple[float, float]]) -> dict:
    """A mechanism given by its description's name (``workspace.described``): its workspace summary (its own
    strokes and home; static forces at rest in N), beside the designs', or {"error": why}."""
    from fmus.mechanism.designs import description
    from fmus.mechanism.kinematics import KinematicsError

    from . import workspace

    out = {"label": name, "source": str(description(name).path), "note": NOT_RUN}
    if grid is None:
        return {**out, "workspace": {"error": "no workspace: none asked for"}}
    try:
        return {**out, "workspace": workspace.summarize(workspace.compute(workspace.machine(name), grid[0], grid[1]))}
    except (ValueError, KinematicsError) as exc:
        return {**out, "workspace": {"error": f"no workspace: {exc}"}}


WORKSPACE_COLUMNS = ("workspace_m_deg2", "margin_min", "margin_home", "singularity_distance_home_m")


def volume_key(ws: Mapping) -> str:
    """The key of a workspace summary's volume in m and deg (the 3PRS: volume_m_deg2; a mechanism with other
    coordinates its own, volume_m3 for x, y, z): the summary gives it after the one in m and rad."""
    return [k for k in ws if k.startswith("volume_")][-1]


def workspace_columns(ws: Optional[dict]) -> dict:
    """The workspace figures a comparison row carries (None without a workspace): its volume as
    ``workspace_<unit>`` (the 3PRS: workspace_m_deg2), the margins."""
    if not ws or "error" in ws:
        return {}
    return {
        "workspace_" + volume_key(ws)[len("volume_") :]: ws[volume_key(ws)],
        "margin_min": ws["smallest_margin"]["value"],
        "margin_home": min(ws["home"]["margin_parallel"], ws["home"]["margin_inverse"]),
        "singularity_distance_home_m": ws["distance_to_singularity_at_home_m"],
    }


def _attached(c: Candidate) -> Optional[bool]:
    if "attached" in c.parameters:
        return bool(c.parameters["attached"])
    return None


def fig10(comp: Comparison) -> Optional[dict]:
    """Bandwidth of the z motion with and without the mechanism (paper Fig. 10), when both ran."""
    if "z" not in comp.test_set.axes:
        return None
    alone = [c for c in comp.candidates if _attached(c) is False]
    loaded = [c for c in comp.candidates if _attached(c) is not False]
    if not alone or not loaded:
        return None
    return {
        "actuators_alone": {c.label: comp.row(c.label, "z")["bandwidth_Hz"] for c in alone},
        "with_mechanism": {c.label: comp.row(c.label, "z")["bandwidth_Hz"] for c in loaded},
        "paper_Hz": {"actuators_alone": paper.BANDWIDTH_ACTUATORS_ALONE, "with_mechanism": paper.BANDWIDTH_WITH_MAST},
    }


SUMMARY_COLUMNS = (
    "design",
    "motion",
    "amplitude",
    "payload_kg",
    "bandwidth_Hz",
    "bandwidth_note",
    "torque_peak_Nm",
    "torque_rms_Nm",
    "current_peak_A",
    "tracking_peak",
    "tracking_peak_rel",
    "tracking_peak_f_min",
    "parasitic_x_m",
    "parasitic_y_m",
    "parasitic_phi_rad",
    "tests",
    "failed",
    "sizing_verdict",
    "sizing_limiting",
    "sizing_margin",
    "sizing_holds_up_to_Hz",
    "sizing_note",
) + WORKSPACE_COLUMNS
RUN_COLUMNS = (
    "design",
    "motion",
    "frequency_Hz",
    "amplitude",
    "magnitude",
    "magnitude_dB",
    "phase_deg",
    "torque_peak_Nm",
    "torque_rms_Nm",
    "current_peak_A",
    "tracking_peak",
    "parasitic_x_m",
    "parasitic_y_m",
    "parasitic_phi_rad",
    "error",
)


def _run_row(label: str, r: SineResult, parasitic: Sequence[str] = ("x", "y", "phi")) -> dict:
    ok = not r.error
    return {
        "design": label,
        "motion": r.axis,
        "frequency_Hz": r.frequency,
        "amplitude": r.amplitude,
        "magnitude": r.magnitude if ok else None,
        "magnitude_dB": 20 * math.log10(r.magnitude) if ok and r.magnitude > 0 else None,
        "phase_deg": r.phase_deg if ok else None,
        "torque_peak_Nm": max(r.torque_peak) if ok else None,
        "torque_rms_Nm": max(r.torque_rms) if ok else None,
        "current_peak_A": max(r.current_peak) if ok and r.current_peak else None,
        "tracking_peak": r.tracking_peak if ok else None,
        **{parasitic_column(c): r.parasitic.get(c) if ok else None for c in parasitic},
        "error": r.error or "",
    }


def columns(base: Sequence[str], rows: Sequence[Mapping]) -> tuple[str, ...]:
    """``base`` (the 3PRS's columns) with its parasitic_* and workspace volume columns replaced by those ``rows``
    have (pose order; for the 3PRS the same), the base's when they have none."""
    keys = dict.fromkeys(k for r in rows for k in r)
    parasitic = tuple(parasitic_column(c) for c in POSE if parasitic_column(c) in keys)
    volumes = tuple(k for k in keys if k.startswith("workspace_"))
    out: list[str] = []
    for col in base:
        if col.startswith("parasitic_"):
            out += [c for c in parasitic or (col,) if c not in out]
        elif col.startswith("workspace_"):
            out += volumes or [col]
        else:
            out.append(col)
    return tuple(out)


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def _renamed(rows: Sequence[dict], kind: str) -> list[dict]:
    """Rows with their first key, "design", named after what the candidates are."""
    return [{(kind if k == "design" else k): v for k, v in r.items()} for r in rows]


def robustness(comp: Comparison) -> list[dict]:
    """Per controller and motion: bandwidth and peak tracking error, as designed and with the unknown payload."""
    rows = []
    for c in comp.candidates:
        if not c.nominal:
            continue
        for axis in comp.test_set.axes:
            nom, pay = comp.row(c.nominal, axis), comp.row(c.label, axis)
            row = {
                "controller": c.nominal,
                "motion": axis,
                "payload_kg": c.payload_kg,
                "bandwidth_Hz": nom["bandwidth_Hz"],
                "bandwidth_payload_Hz": pay["bandwidth_Hz"],
            }
            for key in ("tracking_peak", "tracking_peak_f_min"):
                row[key], row[f"{key}_payload"] = nom[key], pay[key]
                row[f"{key}_ratio"] = pay[key] / nom[key] if pay[key] and nom[key] else None
            rows.append(row)
    return rows


def write(comp: Comparison, out: Path, plots: bool = True) -> list[Path]:
    """comparison.csv/.json/.md, runs.csv and the plots."""
    files = []
    kind = comp.kind
    with open(out / "comparison.csv", "w", newline="") as handle:
        w = csv.DictWriter(handle, (kind,) + columns(SUMMARY_COLUMNS, comp.summary)[1:], extrasaction="ignore")
        w.writeheader()
        w.writerows(_renamed(comp.summary, kind))
        w.writerows(
            _renamed(
                [
                    {"design": d["label"], "motion": "", "sizing_note": d["note"], **workspace_columns(d["workspace"])}
                    for d in comp.descriptions
                ],
                kind,
            )
        )
    files.append(out / "comparison.csv")
    runs = _renamed(
        [
            _run_row(label, r, comp.parasitic.get(label, ("x", "y", "phi")))
            for (label, _), rs in comp.results.items()
            for r in rs
        ],
        kind,
    )
    with open(out / "runs.csv", "w", newline="") as handle:
        w = csv.DictWriter(handle, (kind,) + columns(RUN_COLUMNS, runs)[1:])
        w.writeheader()
        w.writerows(runs)
    files.append(out / "runs.csv")
    data = {
        f"{kind}s": [
            {
                "label": c.label,
                "source": c.source,
                "system": c.ssp,
                "parameters": c.parameters,
                "payload_kg": c.payload_kg,
                **({"workspace": c.workspace} if c.workspace else {}),
            }
            for c in comp.candidates
        ],
        "test_set": {
            "axes": list(comp.test_set.axes),
            "frequencies_Hz": list(comp.test_set.frequencies),
            "amplitudes": dict(comp.test_set.amplitudes),
            "amplitude_units": {a: POSE_UNITS[a] for a in comp.test_set.amplitudes},
        },
        "summary": _renamed(comp.summary, kind),
        "runs": runs,
        "fig10": fig10(comp) if kind == "design" else None,
        "robustness": robustness(comp),
        **({"descriptions": comp.descriptions} if comp.descriptions else {}),
        **({"extra_motions": {k: list(v) for k, v in comp.extra.items()}} if comp.extra else {}),
    }
    (out / "comparison.json").write_text(json.dumps(data, indent=2))
    files.append(out / "comparison.json")
    parasitic = [c for c in columns(SUMMARY_COLUMNS, comp.summary) if c.startswith("parasitic_")]
    lines = [
        f"| {kind} | motion | bandwidth [Hz] | peak torque [N m] | RMS torque [N m] | peak current [A] "
        "| peak tracking error | "
        + " | ".join(f"parasitic {c.split('_')[1]} [{c.split('_')[2]}]" for c in parasitic)
        + " | failed | drives (mast sizing) | limiting item | margin | drives hold up to [Hz] |",
        "|---|---|---|---|---|---|---|" + "---|" * len(parasitic) + "---|---|---|---|---|",
    ]
    for r in comp.summary:
        unit = POSE_UNITS[r["motion"]]
        bw = _fmt(r["bandwidth_Hz"]) if r["bandwidth_Hz"] is not None else r["bandwidth_note"]
        lines.append(
            f"| {r['design']} | {r['motion']} | {bw} | {_fmt(r['torque_peak_Nm'])} | {_fmt(r['torque_rms_Nm'])} "
            f"| {_fmt(r['current_peak_A'])} "
            f"| {_fmt(r['tracking_peak'])} {unit} | "
            + " | ".join(_fmt(r.get(c)) for c in parasitic)
            + f" | {r['failed']}/{r['tests']} "
            f"| {r.get('sizing_verdict') or '-'} | {r.get('sizing_limiting') or r.get('sizing_note') or '-'} "
            f"| {_fmt(100 * r['sizing_margin']) + ' %' if r.get('sizing_margin') is not None else '-'} "
            f"| {_fmt(r.get('sizing_holds_up_to_Hz'))} |"
        )
    if comp.extra:
        lines += [
            "",
            "Motions beyond the common ones (not in the test set; a 3-DOF design's parasitic motions there): "
            + "; ".join(f"{label}: {', '.join(extra)}" for label, extra in comp.extra.items()),
        ]
    spaces = [(c.label, c.workspace) for c in comp.candidates if c.workspace]
    spaces += [(f"{d['label']} (description, not run)", d["workspace"]) for d in comp.descriptions]
    if spaces:
        ok = [w for _, w in spaces if "error" not in w]
        ranges = list(dict.fromkeys(k for w in ok for k in w["ranges_through_home"])) or ["z_m", "psi_deg", "theta_deg"]
        volumes = list(dict.fromkeys(volume_key(w) for w in ok)) or ["volume_m_deg2"]
        one = len(volumes) == 1  # one unit: in the header, else in each cell
        lines += [
            "",
            "Workspace (`mast workspace`: within the strokes, on the home branch, at least "
            f"{spaces[0][1].get('margin_limit', '-')} m/m from a singularity, connected to home):",
            "",
            f"| design | volume{f' [{unit_text(volumes[0][7:])}]' if one else ''} | "
            + " | ".join(f"{k.rpartition('_')[0]} through home [{k.rpartition('_')[2]}]" for k in ranges)
            + " | smallest margin [m/m] | margin at home [m/m] | home to singularity [m] | worst dexterity |",
            "|---|---|" + "---|" * len(ranges) + "---|---|---|---|",
        ]
        for label, w in spaces:
            if "error" in w:
                lines.append(f"| {label} | {w['error']} |" + " |" * (len(ranges) + 4))
                continue
            r = w["ranges_through_home"]

            def rng(k: str, r: dict = r) -> str:
                if k not in r:
                    return "-"
                if k.endswith("_deg"):
                    return f"{r[k][0]:.3g} .. {r[k][1]:.3g}"
                return f"{r[k][0]:.4g} .. {r[k][1]:.4g}"

            cols = workspace_columns(w)
            volume = _fmt(w[volume_key(w)]) + ("" if one else f" {unit_text(volume_key(w)[7:])}")
            lines.append(
                f"| {label} | {volume} | "
                + " | ".join(rng(k) for k in ranges)
                + f" | {_fmt(cols['margin_min'])} | {_fmt(cols['margin_home'])} "
                f"| {_fmt(cols['singularity_distance_home_m'])} | {_fmt(w['worst_dexterity']['value'])} |"
            )
    if comp.descriptions:
        lines += _static_lines(spaces) + ["", *(f"{d['label']}: {d['note']}." for d in comp.descriptions)]
    f10 = data["fig10"]
    if f10:
        lines += [
            "",
            "Paper Fig. 10, z motion -3 dB bandwidth: "
            + "; ".join(f"{k} {_fmt(v)} Hz" for k, v in f10["with_mechanism"].items())
            + " with the mechanism, "
            + "; ".join(f"{k} {_fmt(v)} Hz" for k, v in f10["actuators_alone"].items())
            + f" actuators alone (paper: {paper.BANDWIDTH_WITH_MAST} and {paper.BANDWIDTH_ACTUATORS_ALONE} Hz).",
        ]
    if data["robustness"]:
        lines += [
            "",
            "Robustness: the same tests with a payload on the platform that the controllers do not know "
            "(their models keep the nominal sets).",
            "",
            f"| controller | motion | payload [kg] | bandwidth [Hz] | with payload [Hz] | tracking error at "
            f"{min(comp.test_set.frequencies):g} Hz | with payload | ratio | peak tracking error | with payload "
            "| ratio |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in data["robustness"]:
            unit = POSE_UNITS[r["motion"]]
            lines.append(
                f"| {r['controller']} | {r['motion']} | {_fmt(r['payload_kg'])} | {_fmt(r['bandwidth_Hz'])} "
                f"| {_fmt(r['bandwidth_payload_Hz'])} | {_fmt(r['tracking_peak_f_min'])} {unit} "
                f"| {_fmt(r['tracking_peak_f_min_payload'])} {unit} | {_fmt(r['tracking_peak_f_min_ratio'])} "
                f"| {_fmt(r['tracking_peak'])} {unit} | {_fmt(r['tracking_peak_payload'])} {unit} "
                f"| {_fmt(r['tracking_peak_ratio'])} |"
            )
    (out / "comparison.md").write_text("\n".join(lines) + "\n")
    files.append(out / "comparison.md")
    if plots and comp.candidates:
        files += _plots(comp, out)
        if kind == "controller":
            files += _motion_plots(comp, out)
    return files


def _static_lines(spaces: Sequence[tuple[str, dict]]) -> list[str]:
    """comparison.md's table of the static actuator forces at rest (``mast workspace``'s static_forces): at home
    and the largest inside the workspace, where the workspace gives them."""
    lines = [
        "",
        "Static forces of the mechanism on its drives at rest (`mast workspace`; a carriage the actuator model "
        "carries, M_load, is not in them, as the 3PRS's; one that is a body of the mechanism is, as the "
        "3RPS's):",
        "",
        "| design | at home [N] | largest inside [N] | at |",
        "|---|---|---|---|",
    ]
    for label, w in spaces:
        forces = w.get("static_forces", {}) if "error" not in w else {}
        home = next((v for k, v in forces.items() if k.startswith("home_")), None)
        largest = next(
            (v for k, v in forces.items() if k.startswith("largest_") and k != "largest_motor_torque_Nm"), None
        )
        if home is None:
            lines.append(f"| {label} | {forces.get('not_computed', '-')} | | |")
            continue
        at = ", ".join(f"{k.rpartition('_')[0]} = {_fmt(v)} {k.rpartition('_')[2]}" for k, v in forces["at"].items())
        lines.append(f"| {label} | {', '.join(_fmt(v) for v in home)} | {_fmt(largest)} | {at} |")
    return lines


def _motion_plots(comp: Comparison, out: Path) -> list[Path]:
    """motion_<axis>.png: magnitude, peak tracking error and peak torque against frequency per controller,
    as designed (solid) and with the unknown payload (dashed, same colour)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []
    nominal = [c for c in comp.candidates if not c.nominal]
    loaded = {c.nominal: c for c in comp.candidates if c.nominal}
    panels = (
        ("magnitude [dB]", lambda r: 20 * math.log10(r.magnitude)),
        ("peak tracking error [m or rad]", lambda r: r.tracking_peak),
        ("peak motor torque [N m]", lambda r: max(r.torque_peak)),
    )
    for axis in comp.test_set.axes:
        fig, ax = plt.subplots(1, 3, figsize=(14, 4))
        for k, c in enumerate(nominal):
            colour = f"C{k}"
            for cand, style in ((c, "o-"), (loaded.get(c.label), "s--")):
                if cand is None:
                    continue
                rs = [r for r in comp.results[(cand.label, axis)] if not r.error]
                for a, (_, get) in zip(ax, panels):
                    a.plot([r.frequency for r in rs], [get(r) for r in rs], style, color=colour, ms=3, label=cand.label)
        for a, (title, _) in zip(ax, panels):
            a.set_xscale("log")
            a.set_xlabel("frequency [Hz]")
            a.set_title(title, fontsize=9)
            a.grid(True, lw=0.3)
        ax[0].axhline(-3.0, color="0.5", lw=0.8, ls="--")
        ax[1].set_yscale("log")
        ax[0].legend(fontsize=7)
        amplitude = comp.test_set.amplitudes[axis]
        fig.suptitle(
            f"{axis} motion, amplitude {amplitude:g} {POSE_UNITS[axis]}: controllers as designed "
            f"(solid) and with a payload they do not know (dashed)"
        )
        fig.tight_layout()
        fig.savefig(out / f"motion_{axis}.png", dpi=110)
        plt.close(fig)
        files.append(out / f"motion_{axis}.png")
    return files


def _plots(comp: Comparison, out: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    axes_ = comp.test_set.axes
    labels = [c.label for c in comp.candidates]
    files = []
    freqs = sorted(comp.test_set.frequencies)

    def freq_axis(a) -> None:
        a.set_xscale("log")
        a.set_xticks(freqs, [f"{f:g}" for f in freqs])
        a.minorticks_off()
        a.grid(True, lw=0.3)

    def series(label, axis, get):
        rs = [r for r in comp.results[(label, axis)] if not r.error]
        return [r.frequency for r in rs], [get(r) for r in rs]

    # Bode: magnitude and phase per motion
    fig, ax = plt.subplots(2, len(axes_), figsize=(4.5 * len(axes_), 6.5), squeeze=False, sharex=True)
    for j, axis in enumerate(axes_):
        for label in labels:
            f, mag = series(label, axis, lambda r: 20 * math.log10(r.magnitude))
            ax[0][j].semilogx(f, mag, "o-", ms=3, label=label)
            f, ph = series(label, axis, lambda r: r.phase_deg)
            ax[1][j].semilogx(f, ph, "o-", ms=3, label=label)
        ax[0][j].axhline(-3.0, color="0.5", lw=0.8, ls="--")
        ax[0][j].set_title(f"{axis} motion")
        ax[0][j].set_ylabel("magnitude [dB]")
        ax[1][j].set_ylabel("phase [deg]")
        ax[1][j].set_xlabel("frequency [Hz]")
        for a in (ax[0][j], ax[1][j]):
            freq_axis(a)
    ax[0][0].legend(fontsize=8)
    fig.suptitle("closed-loop pose response (achieved / commanded)")
    fig.tight_layout()
    fig.savefig(out / "bode.png", dpi=110)
    plt.close(fig)
    files.append(out / "bode.png")

    # bandwidth bars
    fig, ax = plt.subplots(figsize=(1.6 + 1.4 * len(axes_) * max(1, len(labels)) / 2, 4))
    width = 0.8 / max(1, len(labels))
    for k, label in enumerate(labels):
        bws = [comp.row(label, axis)["bandwidth_Hz"] for axis in axes_]
        xs = [j + (k - (len(labels) - 1) / 2) * width for j in range(len(axes_))]
        bars = ax.bar(xs, [b if b is not None else 0.0 for b in bws], width, label=label)
        for bar, b in zip(bars, bws):
            ax.text(
                bar.get_x() + bar.get_width() / 2,
                bar.get_height(),
                "n/a" if b is None else f"{b:.2f}",
                ha="center",
                va="bottom",
                fontsize=7,
            )
    ax.set_xticks(range(len(axes_)), [f"{a} motion" for a in axes_])
    ax.set_ylabel("-3 dB bandwidth [Hz]")
    ax.legend(fontsize=8)
    ax.grid(True, axis="y", lw=0.3)
    fig.tight_layout()
    fig.savefig(out / "bandwidth.png", dpi=110)
    plt.close(fig)
    files.append(out / "bandwidth.png")

    def per_frequency(name, ylabel, title, getters):
        fig, ax = plt.subplots(
            len(getters), len(axes_), figsize=(4.5 * len(axes_), 3.2 * len(getters)), squeeze=False, sharex=True
        )
        for i, (sub, get) in enumerate(getters):
            for j, axis in enumerate(axes_):
                for label in labels:
                    f, y = series(label, axis, get)
                    ax[i][j].semilogx(f, y, "o-", ms=3, label=label)
                ax[i][j].ticklabel_format(axis="y", style="sci", scilimits=(-3, 3))
                ax[i][j].set_title(f"{axis} motion: {sub}", fontsize=9)
                ax[i][j].set_ylabel(ylabel[i] if isinstance(ylabel, (list, tuple)) else ylabel)
                freq_axis(ax[i][j])
                ax[-1][j].set_xlabel("frequency [Hz]")
        ax[0][0].legend(fontsize=8)
        fig.suptitle(title)
        fig.tight_layout()
        fig.savefig(out / name, dpi=110)
        plt.close(fig)
        files.append(out / name)

    per_frequency(
        "torque.png",
        ["N m", "N m"],
        "motor torque, steady state (largest motor)",
        [("peak", lambda r: max(r.torque_peak)), ("RMS", lambda r: max(r.torque_rms))],
    )
    per_frequency(
        "tracking.png", "m (z) / rad", "peak tracking error, steady state", [("peak error", lambda r: r.tracking_peak)]
    )
    parasitic = [c for c in POSE if any(c in p for p in comp.parasitic.values())] or ["x", "y", "phi"]
    per_frequency(
        "parasitic.png",
        [POSE_UNITS[c] for c in parasitic],
        "parasitic motions: half peak-to-peak, steady state",
        [(c, lambda r, c=c: r.parasitic.get(c, math.nan)) for c in parasitic],
    )
    return files
