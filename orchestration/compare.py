"""`mast compare`: run one test set on several mechanism designs; write a table and plots.

A design is given as a mechanism FMU (or as a whole system, .ssp/.ssd). For an FMU the
system is the base system (``ssp/MAST.ssd``) with the mechanism swapped, exactly as a user
would swap it by hand in the SSP (docs/interfaces.md, "Writing a mechanism FMU"):

- the ``mechanism`` component's source is the FMU, bound to the FMU's own default parameters
  (the design is what the FMU says it is);
- the controller's kinematic model (``kinematics``, H, r, L, alpha_1..3, beta: the FMU's
  values of the geometry parameters it declares) is bound after the controller's sets;
- the actuators' gravity along the guides is g cos(beta) when the FMU declares ``beta``.

The test set is pure sine motions in z, psi and theta at several frequencies around the
home pose (paper section 4.1; amplitudes of ``paper.AMPLITUDE``). For every design and
motion: the closed-loop -3 dB bandwidth, peak and RMS motor torque, peak tracking error and
parasitic motion amplitudes. Outputs in DIR: comparison.csv (one row per design and motion),
runs.csv (one row per sine test), comparison.json (everything), comparison.md (the table),
bode.png, bandwidth.png, torque.png, tracking.png, parasitic.png, and systems/*.ssp (the
systems that were run, for `mast run`).
"""
from __future__ import annotations

import csv
import json
import math
import re
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Optional, Sequence, Union

from fmus.common.parameters import Value
from fmus.mechanism.designs import KINEMATIC_PARAMETERS_NAMES

from . import paper
from .frequency import SineCase, SineResult, bandwidth, run_cases

REPO = Path(__file__).resolve().parents[1]
BASE_SSD = REPO / "ssp" / "MAST.ssd"
FMU_DIR = REPO / "build" / "fmus"
MOTIONS = ("z", "psi", "theta")
#: geometry parameters the controller's kinematic model takes from the mechanism FMU
KINEMATIC_NAMES = KINEMATIC_PARAMETERS_NAMES


@dataclass(frozen=True)
class TestSet:
    """Sine motions: for each axis, each frequency [Hz], amplitude in m (z) or rad (psi, theta)."""

    __test__ = False      # not a pytest test class

    axes: tuple[str, ...] = MOTIONS
    frequencies: tuple[float, ...] = (0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0)
    amplitudes: Mapping[str, float] = field(default_factory=lambda: dict(paper.AMPLITUDE))


#: the default set: about 1 minute per design on 2 cores
DEFAULT = TestSet()
#: the smallest useful set (tests, smoke runs): z only, around the bandwidth
QUICK = TestSet(axes=("z",), frequencies=(1.0, 4.0, 8.0))


@dataclass
class Candidate:
    """One design to compare: a label, the system to run, where it came from."""

    label: str
    ssp: str
    source: str
    parameters: dict = field(default_factory=dict)   # the mechanism FMU's defaults (empty for a system)


@dataclass
class Comparison:
    """What ``compare`` found; ``summary`` rows are what comparison.csv holds."""

    candidates: list[Candidate]
    test_set: TestSet
    results: dict                 # (label, axis) -> list[SineResult], in test-set frequency order
    summary: list[dict]
    wall_time_s: float
    files: list[Path]

    def row(self, label: str, axis: str) -> dict:
        for r in self.summary:
            if r["design"] == label and r["motion"] == axis:
                return r
        raise KeyError((label, axis))


# ----------------------------------------------------------------------------- systems
def fmu_parameters(fmu: Union[str, Path]) -> dict[str, Value]:
    """Default (start) values of an FMU's parameters, typed."""
    from fmpy import read_model_description

    md = read_model_description(str(fmu))
    convert = {"Real": float, "Integer": int, "Enumeration": int, "String": str,
               "Boolean": lambda s: str(s).strip().lower() in ("true", "1")}
    out: dict[str, Value] = {}
    for v in md.modelVariables:
        if v.causality == "parameter" and v.start is not None:
            out[v.name] = convert.get(v.type, str)(v.start)
    return out


def _parameter_set_xml(values: Mapping[str, Value], name: str, why: str, indent: str) -> str:
    """An inline ssd:ParameterBinding holding ``values``."""
    rows = []
    for key, value in values.items():
        if isinstance(value, bool):
            kind, text = "Boolean", "true" if value else "false"
        elif isinstance(value, int):
            kind, text = "Integer", str(value)
        elif isinstance(value, float):
            kind, text = "Real", repr(value)
        else:
            kind, text = "String", str(value).replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;")
        rows.append(f'{indent}        <ssv:Parameter name="{key}" description="{why}"><ssv:{kind} value="{text}"/>'
                    f'</ssv:Parameter>')
    body = "\n".join(rows)
    return (f'{indent}<ssd:ParameterBinding>\n{indent}  <ssd:ParameterValues>\n'
            f'{indent}    <ssv:ParameterSet version="1.0" name="{name}">\n{indent}      <ssv:Parameters>\n'
            f'{body}\n{indent}      </ssv:Parameters>\n{indent}    </ssv:ParameterSet>\n'
            f'{indent}  </ssd:ParameterValues>\n{indent}</ssd:ParameterBinding>')


def _bindings_span(block: str) -> tuple[str, int, int, bool]:
    """(indent, start, end, exists) of a component's ParameterBindings, or where to create them."""
    found = re.search(r"\n([ \t]*)<ssd:ParameterBindings>.*?</ssd:ParameterBindings>", block, re.S)
    if found:
        return found.group(1), found.start(), found.end(), True
    at = re.search(r"\n([ \t]*)</ssd:Connectors>", block)
    if at is None:
        raise ValueError("a component to bind parameters to declares no connectors")
    return at.group(1), at.end(), at.end(), False


def swapped_ssd(base_text: str, fmu_name: str, params: Mapping[str, Value], label: str) -> str:
    """The base system's text with its ``mechanism`` swapped for the FMU (module docstring)."""
    mechanism_found = False

    def component(m: re.Match) -> str:
        nonlocal mechanism_found
        block = m.group(0)
        name = re.search(r'\bname="([^"]*)"', block).group(1)
        source = re.search(r'\bsource="([^"]*)"', block).group(1)
        if name == "mechanism":       # its own defaults replace whatever the base bound
            mechanism_found = True
            block = block.replace(f'source="{source}"', f'source="resources/{fmu_name}"', 1)
            pad, start, end, _ = _bindings_span(block)
            inline = _parameter_set_xml(params, "design", f"default of {fmu_name}", pad + "  ")
            return block[:start] + f"\n{pad}<ssd:ParameterBindings>\n{inline}\n{pad}</ssd:ParameterBindings>" + block[end:]
        extra, why = {}, ""
        if name == "controller":
            extra = {k: params[k] for k in KINEMATIC_NAMES if k in params}
            why = f"the controller's kinematic model: the geometry of {fmu_name}"
        elif Path(source).stem == "MastActuator" and "beta" in params and "g" in params:
            extra = {"g_guide": float(params["g"]) * math.cos(float(params["beta"]))}
            why = f"gravity along the guides of {fmu_name}: g cos(beta)"
        if not extra:
            return block
        pad, start, end, exists = _bindings_span(block)
        inline = _parameter_set_xml(extra, "design", why, pad + "  ")
        if not exists:
            return block[:start] + f"\n{pad}<ssd:ParameterBindings>\n{inline}\n{pad}</ssd:ParameterBindings>" + block[end:]
        last = list(re.finditer(r"<ssd:ParameterBinding\b[^>]*/>|</ssd:ParameterBinding>", block[:end]))[-1]
        return block[:last.end()] + "\n" + inline + block[last.end():]     # bound last: it overrides

    text = re.sub(r"<ssd:Component\b.*?</ssd:Component>", component, base_text, flags=re.S)
    if not mechanism_found:
        raise ValueError("the base system has no component named 'mechanism' to swap")
    text = re.sub(r'(<ssd:SystemStructureDescription\b[^>]*?\bname=")[^"]*(")', rf"\g<1>MAST_{label}\g<2>", text,
                  count=1)
    return text


def _label(path: Path, taken: set) -> str:
    base = re.sub(r"[^A-Za-z0-9_]+", "_", path.stem) or "design"
    label, k = base, 2
    while label in taken:
        label, k = f"{base}_{k}", k + 1
    taken.add(label)
    return label


def prepare(mechanisms: Sequence[Union[str, Path]], out: Union[str, Path], base_ssd: Union[str, Path] = BASE_SSD,
            fmu_dir: Union[str, Path] = FMU_DIR) -> list[Candidate]:
    """One runnable system per design: an FMU is swapped into ``base_ssd`` (packed into
    out/systems/<label>.ssp with the FMUs of ``fmu_dir`` for the other components); an .ssp or
    .ssd is used as it is."""
    from .build import build_ssp

    out, base_ssd, fmu_dir = Path(out), Path(base_ssd), Path(fmu_dir)
    candidates: list[Candidate] = []
    taken: set = set()
    base_text = base_ssd.read_text(encoding="utf-8")
    for item in mechanisms:
        path = Path(item)
        if not path.exists():
            raise FileNotFoundError(f"mechanism {path}: no such file")
        label = _label(path, taken)
        if path.suffix in (".ssp", ".ssd"):
            from .ssp import SSPArchive

            with SSPArchive(path) as archive:      # the mechanism's bound parameters (attached, geometry ...)
                comp = archive.system.components.get("mechanism")
                params = dict(comp.parameters) if comp is not None else {}
            candidates.append(Candidate(label, str(path), str(path), params))
            continue
        if path.suffix != ".fmu":
            raise ValueError(f"mechanism {path}: expected an .fmu (a mechanism to swap in) or an .ssp/.ssd (a system)")
        params = fmu_parameters(path)
        with tempfile.TemporaryDirectory(prefix="mast_compare_") as tmp:
            tmp = Path(tmp)
            shutil.copytree(base_ssd.parent / "resources", tmp / "resources",
                            ignore=shutil.ignore_patterns("*.fmu"))
            fmus = tmp / "fmus"
            fmus.mkdir()
            for fmu in fmu_dir.glob("*.fmu"):
                (fmus / fmu.name).symlink_to(fmu.resolve())
            target = fmus / path.name
            if target.exists() or target.is_symlink():
                target.unlink()
            target.symlink_to(path.resolve())
            ssd = tmp / f"{label}.ssd"
            ssd.write_text(swapped_ssd(base_text, path.name, params, label), encoding="utf-8")
            ssp = build_ssp(ssd, fmus, out / "systems")
        candidates.append(Candidate(label, str(ssp), str(path), params))
    return candidates


# ----------------------------------------------------------------------------- the comparison
def _finite(x: Optional[float]) -> Optional[float]:
    return x if x is not None and math.isfinite(x) else None


def summarize(label: str, axis: str, amplitude: float, results: Sequence[SineResult]) -> dict:
    ok = [r for r in results if not r.error]
    freqs = [r.frequency for r in ok]
    bw = bandwidth(freqs, [r.ratio for r in ok]) if len(ok) > 1 else None
    peak = max((max(r.torque_peak) for r in ok), default=math.nan)
    rms = max((max(r.torque_rms) for r in ok), default=math.nan)
    track = max((r.tracking_peak for r in ok), default=math.nan)
    par = {k: max((r.parasitic.get(k, math.nan) for r in ok), default=math.nan) for k in ("x", "y", "phi")}
    return {
        "design": label, "motion": axis, "amplitude": amplitude,
        "bandwidth_Hz": bw,
        "bandwidth_note": ("" if bw is not None else
                           (f"above {max(freqs):g} Hz" if ok and abs(ok[-1].ratio) >= 10 ** (-3 / 20)
                            else "not found")),
        "torque_peak_Nm": _finite(peak), "torque_rms_Nm": _finite(rms),
        "tracking_peak": _finite(track), "tracking_peak_rel": _finite(track / amplitude) if amplitude else None,
        "parasitic_x_m": _finite(par["x"]), "parasitic_y_m": _finite(par["y"]), "parasitic_phi_rad": _finite(par["phi"]),
        "tests": len(results), "failed": len(results) - len(ok),
        "errors": sorted({r.error for r in results if r.error}),
    }


def compare(mechanisms: Sequence[Union[str, Path]], out: Union[str, Path], test_set: Optional[TestSet] = None,
            quick: bool = False, workers: Optional[int] = None, direct: bool = False,
            parameters: Optional[Mapping[str, Mapping[str, Value]]] = None, base_ssd: Union[str, Path] = BASE_SSD,
            fmu_dir: Union[str, Path] = FMU_DIR, plots: bool = True,
            progress: Optional[Callable[[int, int], None]] = None) -> Comparison:
    """Run the test set (``QUICK`` if ``quick``, else ``DEFAULT``) on every design; write DIR (module docstring).

    ``parameters``: overrides applied to every design (``{"actuator_1": {"tau_c": 0.07}}``);
    ``direct``: run the model objects without FMI (only for this project's FMUs).
    """
    t0 = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    test_set = test_set or (QUICK if quick else DEFAULT)
    for axis in test_set.axes:
        if axis not in MOTIONS:
            raise ValueError(f"test set: motion {axis!r}: expected one of {', '.join(MOTIONS)}")
    candidates = prepare(mechanisms, out, base_ssd, fmu_dir)
    cases, keys = [], []
    for c in candidates:
        for axis in test_set.axes:
            for f in test_set.frequencies:
                cases.append(SineCase(c.ssp, axis, test_set.amplitudes[axis], f, parameters, direct, label=c.label))
                keys.append((c.label, axis))
    results_flat = run_cases(cases, workers=workers, progress=progress)
    results: dict = {}
    for key, res in zip(keys, results_flat):
        results.setdefault(key, []).append(res)
    summary = [summarize(c.label, axis, test_set.amplitudes[axis], results[(c.label, axis)])
               for c in candidates for axis in test_set.axes]
    comp = Comparison(candidates, test_set, results, summary, 0.0, [])
    comp.files = write(comp, out, plots=plots)
    comp.wall_time_s = time.perf_counter() - t0
    meta = json.loads((out / "comparison.json").read_text())
    meta["wall_time_s"] = round(comp.wall_time_s, 2)
    (out / "comparison.json").write_text(json.dumps(meta, indent=2))
    return comp


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


SUMMARY_COLUMNS = ("design", "motion", "amplitude", "bandwidth_Hz", "bandwidth_note", "torque_peak_Nm", "torque_rms_Nm",
                   "tracking_peak", "tracking_peak_rel", "parasitic_x_m", "parasitic_y_m", "parasitic_phi_rad",
                   "tests", "failed")
RUN_COLUMNS = ("design", "motion", "frequency_Hz", "amplitude", "magnitude", "magnitude_dB", "phase_deg",
               "torque_peak_Nm", "torque_rms_Nm", "tracking_peak", "parasitic_x_m", "parasitic_y_m",
               "parasitic_phi_rad", "error")


def _run_row(label: str, r: SineResult) -> dict:
    ok = not r.error
    return {"design": label, "motion": r.axis, "frequency_Hz": r.frequency, "amplitude": r.amplitude,
            "magnitude": r.magnitude if ok else None,
            "magnitude_dB": 20 * math.log10(r.magnitude) if ok and r.magnitude > 0 else None,
            "phase_deg": r.phase_deg if ok else None,
            "torque_peak_Nm": max(r.torque_peak) if ok else None, "torque_rms_Nm": max(r.torque_rms) if ok else None,
            "tracking_peak": r.tracking_peak if ok else None,
            "parasitic_x_m": r.parasitic.get("x") if ok else None, "parasitic_y_m": r.parasitic.get("y") if ok else None,
            "parasitic_phi_rad": r.parasitic.get("phi") if ok else None, "error": r.error or ""}


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def write(comp: Comparison, out: Path, plots: bool = True) -> list[Path]:
    """comparison.csv/.json/.md, runs.csv and the plots."""
    files = []
    with open(out / "comparison.csv", "w", newline="") as handle:
        w = csv.DictWriter(handle, SUMMARY_COLUMNS, extrasaction="ignore")
        w.writeheader()
        w.writerows(comp.summary)
    files.append(out / "comparison.csv")
    runs = [_run_row(label, r) for (label, _), rs in comp.results.items() for r in rs]
    with open(out / "runs.csv", "w", newline="") as handle:
        w = csv.DictWriter(handle, RUN_COLUMNS)
        w.writeheader()
        w.writerows(runs)
    files.append(out / "runs.csv")
    data = {
        "designs": [{"label": c.label, "source": c.source, "system": c.ssp, "parameters": c.parameters}
                    for c in comp.candidates],
        "test_set": {"axes": list(comp.test_set.axes), "frequencies_Hz": list(comp.test_set.frequencies),
                     "amplitudes": dict(comp.test_set.amplitudes),
                     "amplitude_units": {"z": "m", "psi": "rad", "theta": "rad"}},
        "summary": comp.summary, "runs": runs, "fig10": fig10(comp),
    }
    (out / "comparison.json").write_text(json.dumps(data, indent=2))
    files.append(out / "comparison.json")
    lines = ["| design | motion | bandwidth [Hz] | peak torque [N m] | RMS torque [N m] | peak tracking error "
             "| parasitic x [m] | parasitic y [m] | parasitic phi [rad] | failed |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in comp.summary:
        unit = "m" if r["motion"] == "z" else "rad"
        bw = _fmt(r["bandwidth_Hz"]) if r["bandwidth_Hz"] is not None else r["bandwidth_note"]
        lines.append(f"| {r['design']} | {r['motion']} | {bw} | {_fmt(r['torque_peak_Nm'])} | {_fmt(r['torque_rms_Nm'])} "
                     f"| {_fmt(r['tracking_peak'])} {unit} | {_fmt(r['parasitic_x_m'])} | {_fmt(r['parasitic_y_m'])} "
                     f"| {_fmt(r['parasitic_phi_rad'])} | {r['failed']}/{r['tests']} |")
    f10 = data["fig10"]
    if f10:
        lines += ["", "Paper Fig. 10, z motion -3 dB bandwidth: "
                  + "; ".join(f"{k} {_fmt(v)} Hz" for k, v in f10["with_mechanism"].items()) + " with the mechanism, "
                  + "; ".join(f"{k} {_fmt(v)} Hz" for k, v in f10["actuators_alone"].items())
                  + f" actuators alone (paper: {paper.BANDWIDTH_WITH_MAST} and {paper.BANDWIDTH_ACTUATORS_ALONE} Hz)."]
    (out / "comparison.md").write_text("\n".join(lines) + "\n")
    files.append(out / "comparison.md")
    if plots:
        files += _plots(comp, out)
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
            ax.text(bar.get_x() + bar.get_width() / 2, bar.get_height(), "n/a" if b is None else f"{b:.2f}",
                    ha="center", va="bottom", fontsize=7)
    ax.set_xticks(range(len(axes_)), [f"{a} motion" for a in axes_])
    ax.set_ylabel("-3 dB bandwidth [Hz]")
    ax.legend(fontsize=8)
    ax.grid(True, axis="y", lw=0.3)
    fig.tight_layout()
    fig.savefig(out / "bandwidth.png", dpi=110)
    plt.close(fig)
    files.append(out / "bandwidth.png")

    def per_frequency(name, ylabel, title, getters):
        fig, ax = plt.subplots(len(getters), len(axes_), figsize=(4.5 * len(axes_), 3.2 * len(getters)),
                               squeeze=False, sharex=True)
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

    per_frequency("torque.png", ["N m", "N m"], "motor torque, steady state (largest motor)",
                  [("peak", lambda r: max(r.torque_peak)), ("RMS", lambda r: max(r.torque_rms))])
    per_frequency("tracking.png", "m (z) / rad", "peak tracking error, steady state",
                  [("peak error", lambda r: r.tracking_peak)])
    per_frequency("parasitic.png", ["m", "m", "rad"], "parasitic motions: half peak-to-peak, steady state",
                  [("x", lambda r: r.parasitic.get("x", math.nan)), ("y", lambda r: r.parasitic.get("y", math.nan)),
                   ("phi", lambda r: r.parasitic.get("phi", math.nan))])
    return files
