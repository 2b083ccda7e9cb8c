"""`mast reproduce`: the paper's analyses regenerated from co-simulations of the FMUs.

Writes DIR/report.md with its figures and DIR/paper_table.json, one row per
number the paper reports (``paper.CLAIMS``): quantity, kind (``fit``: a fit used
it; ``reuse``: the same paper number as a fitted row; ``prediction``), paper
value, our value, difference, the tolerance applied (the paper's own 11 % of a
magnitude, 13 % of a phase lag), whether it lies within, and the source. One
parameter set serves every row: the SSP's, in the reading of
ssp/resources/actuator_paper_reading.ssv with the controller gains fitted in it
(controller_paper_reading_fit.ssv, `mast fit-gains`), in the paper's two
physical variants (manufacturer data; identified J1/1.56 and Coulomb friction).
The drive's current limit is part of every test; the report says which tests
touch it.

The reproduction is the paper's, so it is the 3PRS's on purpose: its motions z, psi, theta
(``MOTIONS``), its three motors (``KEEP``, the figures' motor 1..3) and its actuator_1 as the
drive of Table 1. The analyses it is built from (``frequency``, ``compare``, ``metrics``) follow
any mechanism's topology; this module does not, and runs only the MAST's own systems.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..core.build import SSP_SRC  # noqa: E402
from ..core.ssp import SSPArchive  # noqa: E402
from . import paper  # noqa: E402
from .frequency import CountProgress, SineCase, SineResult, bandwidth, harmonic, run_cases  # noqa: E402
from .identify import (
    GAINS_SET,
    IDENTIFIED_SET,
    identified_parameters,
    manufacturer_parameters,  # noqa: E402
    reading_gains,
    resource_parameters,
)

SWEEP_HZ = (0.4, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 6.0, 8.0, 10.0, 14.0, 20.0)
TIME_DOMAIN_HZ = (0.4, 5.0, 10.0)
MOTIONS = ("z", "psi", "theta")
#: what the actuators see "without the MAST" (paper Fig. 10): the mechanism detached (no forces, pose still reported)
NO_MECHANISM = {"mechanism": {"attached": 0}}
#: the motor whose torque the time-domain figures show: one that moves in that motion (T layout)
MOTOR_SHOWN = {"z": 1, "psi": 2, "theta": 1}
#: forensics: extra moving mass per drive [kg] and the frequencies its z bandwidth is read from [Hz]
EXTRA_MASS_KG = (2.27, 6.0)  # 2.27 kg: the MAST lumped on each drive, as Eqs. 21-22 do
MASS_HZ = (2.0, 3.0, 4.0, 5.0, 6.0)
KEEP = (
    "actuator_1.tau_m",
    "actuator_2.tau_m",
    "actuator_3.tau_m",
    "z_cmd",
    "psi_cmd",
    "theta_cmd",
    "mechanism.z",
    "mechanism.psi",
    "mechanism.theta",
)


@dataclass
class Row:
    """One number of the paper against ours: a fit target, a reused number, or a prediction."""

    claim: paper.Claim
    ours: float
    kind: str  # "fit", "reuse" or "prediction" (paper.kind)
    note: str = ""

    @property
    def difference(self) -> float:
        return self.ours - self.claim.value

    @property
    def within(self) -> bool:
        return self.claim.within(self.ours)

    @property
    def tolerance_text(self) -> str:
        lo, hi = self.claim.band()
        rule = "13 % of the phase lag" if self.claim.tolerance == "phase" else "11 %"
        return f"{rule}: [{lo:.4g}, {hi:.4g}]"

    def as_dict(self) -> dict:
        c = self.claim
        return {
            "key": c.key,
            "quantity": c.quantity,
            "unit": c.unit,
            "kind": self.kind,
            "paper": c.value,
            "ours": self.ours,
            "difference": self.difference,
            "tolerance": c.tolerance,
            "tolerance_band": list(c.band()),
            "within_paper_deviation": self.within,
            "statement": c.statement,
            "source": c.source,
            "note": self.note,
        }


def _strict(value):
    """A row as strict JSON: a number that is not finite (NaN: the run failed; an open band's end) is null."""
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_strict(v) for v in value]
    return None if isinstance(value, float) and not math.isfinite(value) else value


def _merge(*sets: Optional[dict]) -> dict:
    out: dict = {}
    for s in sets:
        for element, values in (s or {}).items():
            out.setdefault(element, {}).update(values)
    return out


def plan(ssp: str, direct: bool = False, sweep_hz: tuple[float, ...] = SWEEP_HZ) -> dict[str, list[SineCase]]:
    """Every independent co-simulation of the report, by group."""
    gains = {"controller": reading_gains()}
    ident, manuf = _merge(identified_parameters(), gains), _merge(manufacturer_parameters(), gains)
    # the sweeps with the MAST take their time-domain frequencies from the Sim. Ident. tests (the same runs)
    groups = {
        f"sweep_{m}": [
            SineCase(ssp, m, paper.AMPLITUDE[m], f, ident, direct) for f in sweep_hz if f not in TIME_DOMAIN_HZ
        ]
        for m in MOTIONS
    }
    groups["sweep_z_alone"] = [
        SineCase(ssp, "z", paper.AMPLITUDE["z"], f, _merge(ident, NO_MECHANISM), direct) for f in sweep_hz
    ]
    for name, pset in (("ident", ident), ("manuf", manuf)):
        groups[f"time_{name}"] = [
            SineCase(ssp, m, paper.AMPLITUDE[m], f, pset, direct, KEEP, label=f"{m} {f:g} Hz")
            for m in MOTIONS
            for f in TIME_DOMAIN_HZ
        ]
    # forensics: what extra moving mass per drive does to the z bandwidth (docs/reproduction.md)
    m_star = ident["actuator_1"]["M_load"]
    for extra in EXTRA_MASS_KG:
        heavier = _merge(ident, {a: {"M_load": m_star + extra} for a in ident if a.startswith("actuator")})
        groups[f"mass_{extra:g}"] = [SineCase(ssp, "z", paper.AMPLITUDE["z"], f, heavier, direct) for f in MASS_HZ]
    return groups


def reproduce(
    ssp: str, out: Path, workers: int = 2, direct: bool = False, sweep_hz: tuple[float, ...] = SWEEP_HZ
) -> dict:
    """Run everything, write the report; return a summary (wall time, rows and predictions within tolerance)."""
    t0 = time.perf_counter()
    with SSPArchive(ssp):  # a missing or malformed SSP stops here, before 82 runs fail and a folder is made
        pass
    out.mkdir(parents=True, exist_ok=True)
    groups = plan(ssp, direct, sweep_hz)
    flat = [case for cases in groups.values() for case in cases]
    results = run_cases(flat, workers=workers, progress=CountProgress("reproduce: sine tests"))
    by_group, k = {}, 0
    for name, cases in groups.items():
        by_group[name] = results[k : k + len(cases)]
        k += len(cases)
    for m in MOTIONS:
        shared = [r for r in by_group["time_ident"] if r.axis == m and r.frequency in sweep_hz]
        by_group[f"sweep_{m}"] = sorted(by_group[f"sweep_{m}"] + shared, key=lambda r: r.frequency)
    failures = [
        f"{c.axis} {c.frequency:g} Hz ({c.label or 'sweep'}): {r.error}" for c, r in zip(flat, results) if r.error
    ]

    params = _actuator_params(ssp)
    m_eq22 = float(_component_params(ssp, "actuator_1")["M_load"])  # the SSP's own carriage: Eq. 22's M_load
    i_max = float(_component_params(ssp, "controller")["i_max"])
    ours = {**_actuator_values(params), **_sweep_values(by_group), **_time_values(by_group)}
    limits = _limit_table(by_group, i_max)
    notes = {"torque/excess_10Hz": _limit_note(limits, "z", 10.0)}
    rows = [Row(c, ours.get(c.key, float("nan")), paper.kind(c), notes.get(c.key, "")) for c in paper.CLAIMS]
    figures = [_plot_bode(params, out, m_eq22), _plot_sweeps(by_group, out)] + _plot_time(by_group, out)
    wall = time.perf_counter() - t0
    (out / "paper_table.json").write_text(json.dumps([_strict(r.as_dict()) for r in rows], indent=2, allow_nan=False))
    summary = _summary(rows, wall, len(flat), failures)
    forensics = forensic_values(ssp, params, by_group, m_eq22)
    _write_report(out, rows, figures, failures, summary, ssp, workers, _forensic_lines(forensics), limits, by_group)
    summary["forensics"], summary["limits"] = forensics, limits
    return summary


def _summary(rows: list[Row], wall: float, runs: int, failures: list[str]) -> dict:
    count = {kind: [r for r in rows if r.kind == kind] for kind in ("fit", "reuse", "prediction")}
    return {
        "wall_time_s": wall,
        "runs": runs,
        "rows": len(rows),
        "within": sum(1 for r in rows if r.within),
        "judged": len(rows),
        "predictions": len(count["prediction"]),
        "predictions_within": sum(1 for r in count["prediction"] if r.within),
        "fits": len(count["fit"]),
        "fits_within": sum(1 for r in count["fit"] if r.within),
        "reuses": len(count["reuse"]),
        "reuses_within": sum(1 for r in count["reuse"] if r.within),
        "failures": failures,
    }


# -- our values ---------------------------------------------------------------------
def _component_params(ssp: str, name: str) -> dict:
    with SSPArchive(ssp) as archive:
        return dict(archive.system.components[name].parameters)


def _actuator_params(ssp: str) -> dict:
    """actuator_1 as the reproduction runs it, manufacturer data (Table 1) in the paper reading."""
    return {**_component_params(ssp, "actuator_1"), **manufacturer_parameters()["actuator_1"]}


def _actuator_values(params: dict) -> dict[str, float]:
    from fmus.actuator.model import natural_frequencies

    fn = natural_frequencies(params)
    return {"tf2_resonance": fn["TF2"], "fn_table1": fn["TF1"]}


def _bandwidth(results: list[SineResult]) -> float:
    res = [r for r in results if not r.error]
    return bandwidth([r.frequency for r in res], [r.ratio for r in res]) or float("nan")


def _sweep_values(groups: dict) -> dict[str, float]:
    bw = {
        name: _phase_crossing(groups[name], paper.BANDWIDTH_PHASE_DEG)
        for name in ("sweep_z", "sweep_psi", "sweep_theta", "sweep_z_alone")
    }
    values = {f"bandwidth/{m}": bw[f"sweep_{m}"] for m in MOTIONS}
    values["bandwidth/z_alone"] = bw["sweep_z_alone"]
    values["bandwidth/reduction"] = bw["sweep_z_alone"] - bw["sweep_z"]
    values["alike_below_2hz"] = max(
        (
            abs(abs(a.ratio) - abs(b.ratio)) / abs(b.ratio)
            for a, b in zip(groups["sweep_z"], groups["sweep_z_alone"])
            if a.frequency <= paper.ALIKE_UP_TO_HZ and not (a.error or b.error)
        ),
        default=float("nan"),
    )
    return values


def _ptp(r: SineResult, motor: int = 1) -> float:
    """Peak-to-peak motor torque in steady state [N m] (the swing; the weight's offset drops out)."""
    if r.error or not r.signals:
        return float("nan")
    return float(np.ptp(r.signals[f"actuator_{motor}.tau_m"]))


def _time_values(groups: dict) -> dict[str, float]:
    values = {}
    ident = {(r.axis, r.frequency): r for r in groups["time_ident"]}
    manuf = {(r.axis, r.frequency): r for r in groups["time_manuf"]}
    for m in MOTIONS:
        for f in paper.POSITION_RESPONSE:
            r = ident[(m, f)]
            values[paper.position_key("magnitude", m, f)] = r.magnitude
            values[paper.position_key("phase", m, f)] = r.phase_deg
    # the identified set stands for the measurement ("Sim. Ident." matches the experiment, section 4.2)
    meas04, man04 = _ptp(ident[("z", 0.4)]), _ptp(manuf[("z", 0.4)])
    values["torque/difference_0.4Hz"] = meas04 - man04
    values["torque/error_0.4Hz"] = 1.0 - man04 / meas04
    values["torque/excess_10Hz"] = _ptp(manuf[("z", 10.0)]) - _ptp(ident[("z", 10.0)])
    values["torque/square_0.4Hz"] = float(np.nanmean(ident[("z", 0.4)].torque_h3_h1))
    return values


def _limit_table(groups: dict, i_max: float) -> list[dict]:
    """Per time-domain test: the largest current command against the drive's limit."""
    table = []
    for name, variant in (("time_manuf", "Sim. Manufac."), ("time_ident", "Sim. Ident.")):
        for r in groups[name]:
            peak = max(r.current_peak) if r.current_peak and not r.error else float("nan")
            table.append(
                {
                    "variant": variant,
                    "motion": r.axis,
                    "frequency_Hz": r.frequency,
                    "i_peak_A": peak,
                    "i_max_A": i_max,
                    "at_limit": bool(peak >= i_max * (1 - 1e-6)),
                }
            )
    return table


def _sweep_limits(groups: dict, i_max: float) -> list[str]:
    """The sweep tests whose current command reached the drive's limit (their response is the saturated one)."""
    hits = []
    for name in ("sweep_z", "sweep_psi", "sweep_theta", "sweep_z_alone"):
        freqs = [
            f"{r.frequency:g}"
            for r in groups[name]
            if r.current_peak and not r.error and max(r.current_peak) >= i_max * (1 - 1e-6)
        ]
        if freqs:
            hits.append(f"{name.removeprefix('sweep_')} at {', '.join(freqs)} Hz")
    return hits


def _limit_note(limits: list[dict], motion: str, f: float) -> str:
    hit = [t["variant"] for t in limits if t["motion"] == motion and t["frequency_Hz"] == f and t["at_limit"]]
    return f"{' and '.join(hit)} on the {limits[0]['i_max_A']:g} A current limit" if hit else ""


# -- figures ------------------------------------------------------------------------
def _response(num: np.ndarray, den: np.ndarray, f: np.ndarray) -> np.ndarray:
    s = 2j * np.pi * f
    return np.polyval(num, s) / np.polyval(den, s)


def _plot_bode(params: dict, out: Path, m_eq22: float) -> str:
    """Fig. 7 from ``params`` (the reading), with the resonance Eq. 22's carriage ``m_eq22`` [kg] would give."""
    from fmus.actuator.model import natural_frequencies, transfer_functions

    f = np.geomspace(10.0, 5000.0, 2000)
    fig, (ax_m, ax_p) = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    for name, (num, den) in transfer_functions(params).items():
        resp = _response(num, den, f)
        ax_m.loglog(f, np.abs(resp), label=name)
        ax_p.semilogx(f, np.degrees(np.unwrap(np.angle(resp))), label=name)
    eq22 = natural_frequencies({**params, "M_load": m_eq22})
    fn = natural_frequencies(params)
    for ax in (ax_m, ax_p):
        ax.grid(True, which="both", alpha=0.3)
    ax_m.axvline(fn["TF2"], color="k", ls=":", lw=1)
    ax_m.axvline(eq22["TF2"], color="gray", ls=":", lw=1)
    for value, label, y in (
        (paper.TF2_RESONANCE_FIG7, "paper Fig. 7: TF2 ~900 Hz", 0.2),
        (paper.FN_TABLE1, "paper Table 1: f_n 986.5 Hz", 1.5),
    ):
        ax_m.axvline(value, color="r", ls="--", lw=1)
        ax_m.text(value, ax_m.get_ylim()[0] * 10**y, f" {label}", color="r", fontsize=8)
    ax_m.text(
        fn["TF2"],
        ax_m.get_ylim()[1],
        f"TF2 {fn['TF2']:.0f} Hz, f_n {fn['TF1']:.0f} Hz (M* = {float(params['M_load']):g} kg)  ",
        va="top",
        ha="right",
        fontsize=8,
    )
    ax_m.text(
        eq22["TF2"],
        ax_m.get_ylim()[1] / 20,
        f"TF2 {eq22['TF2']:.0f} Hz with Eq. 22's {m_eq22:g} kg  ",
        va="top",
        ha="right",
        fontsize=8,
        color="gray",
    )
    ax_m.set_ylabel("magnitude [rad/(N m), rad/rad]")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel("frequency [Hz]")
    ax_m.legend(loc="lower left", fontsize="small")
    ax_m.set_title("Fig. 7: actuator transfer functions (Eqs. 2-3, Table 1 with M*)")
    fig.tight_layout()
    fig.savefig(out / "fig7_bode.png", dpi=110)
    plt.close(fig)
    return "fig7_bode.png"


def _plot_sweeps(groups: dict, out: Path) -> str:
    fig, (ax_m, ax_p) = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    labels = {
        "sweep_z": "z, with MAST",
        "sweep_psi": "psi, with MAST",
        "sweep_theta": "theta, with MAST",
        "sweep_z_alone": "z, actuators alone",
    }
    for name, label in labels.items():
        res = [r for r in groups[name] if not r.error]
        f = [r.frequency for r in res]
        ax_m.semilogx(f, [20 * math.log10(r.magnitude) for r in res], "o-", ms=3, label=label)
        ax_p.semilogx(f, [r.phase_deg for r in res], "o-", ms=3, label=label)
    fitted = set(paper.FIT_FREQUENCIES)
    for f, (mag, ph) in paper.POSITION_RESPONSE.items():
        style = dict(marker="s", mfc="none", color="k") if f in fitted else dict(marker="x", color="k")
        ax_m.plot(f, 20 * math.log10(mag), ls="", ms=9, mew=2, **style)
        ax_p.plot(f, ph, ls="", ms=9, mew=2, **style)
    ax_m.plot([], [], "ks", mfc="none", label="paper 4.2, fitted on z")
    ax_m.plot([], [], "kx", label="paper 4.2, predicted")
    ax_p.plot(
        paper.BANDWIDTH_WITH_MAST, paper.BANDWIDTH_PHASE_DEG, "rv", ms=9, label="paper: bandwidth with MAST 3.5 Hz"
    )
    ax_p.plot(
        paper.BANDWIDTH_ACTUATORS_ALONE, paper.BANDWIDTH_PHASE_DEG, "r^", ms=9, label="paper: actuators alone 4 Hz"
    )
    ax_p.axhline(paper.BANDWIDTH_PHASE_DEG, color="gray", ls=":")
    ax_p.legend(fontsize="x-small", loc="lower left")
    ax_m.axhline(-3, color="gray", ls=":")
    ax_m.axvline(paper.ALIKE_UP_TO_HZ, color="gray", ls="--", lw=0.8)
    ax_m.text(paper.ALIKE_UP_TO_HZ, 0.3, " paper: alike up to 2 Hz", fontsize=7, color="gray")
    ax_m.set_ylabel("|X / X_cmd| [dB]")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel("frequency [Hz]")
    for ax in (ax_m, ax_p):
        ax.grid(True, which="both", alpha=0.3)
    ax_m.legend(fontsize="x-small")
    ax_m.set_title("Figs. 8-10: closed-loop position response from co-simulated sine tests")
    fig.tight_layout()
    fig.savefig(out / "fig8_10_frequency_response.png", dpi=110)
    plt.close(fig)
    return "fig8_10_frequency_response.png"


def _plot_time(groups: dict, out: Path) -> list[str]:
    names = []
    for m, fig_no in zip(MOTIONS, (11, 12, 13)):
        fig, axes = plt.subplots(2, len(TIME_DOMAIN_HZ), figsize=(13, 6))
        for col, f in enumerate(TIME_DOMAIN_HZ):
            scale = 1e3 if m == "z" else 180 / math.pi
            for name, style, label in (("time_manuf", "--", "Sim. Manufac."), ("time_ident", "-", "Sim. Ident.")):
                r = next(x for x in groups[name] if x.axis == m and x.frequency == f)
                if r.error or not r.signals:
                    continue
                t = r.signals["time"] - r.signals["time"][0]
                cmd = r.signals[f"{m}_cmd"] * scale
                mean = np.mean(cmd)
                if name == "time_ident":
                    axes[0, col].plot(t, cmd - mean, "k:", label="command")
                    # the paper's reported response (section 4.2) applied to this command
                    mag, ph = paper.POSITION_RESPONSE[f]
                    c = harmonic(r.signals["time"], cmd - mean, f) * mag * np.exp(1j * math.radians(ph))
                    w = 2 * math.pi * f * r.signals["time"]
                    axes[0, col].plot(
                        t,
                        c.real * np.cos(w) - c.imag * np.sin(w),
                        color="r",
                        lw=0.8,
                        alpha=0.7,
                        label=f"paper: {100 * mag:.1f} %, {ph:g} deg",
                    )
                axes[0, col].plot(t, r.signals[f"mechanism.{m}"] * scale - mean, style, label=label)
                joint = MOTOR_SHOWN[m]
                axes[1, col].plot(t, r.signals[f"actuator_{joint}.tau_m"], style, label=f"{label}, motor {joint}")
            axes[0, col].set_title(f"{m}, {f:g} Hz")
            axes[1, col].set_xlabel("time in steady state [s]")
        if m == "z":
            axes[1, 0].set_title("paper: measured - manufacturer about 0.10 N m, 70 %", fontsize=8)
            axes[1, 2].set_title("paper: manufacturer 0.1 N m above the measured", fontsize=8)
        axes[0, 0].set_ylabel(f"{m} [{'mm' if m == 'z' else 'deg'}] around home")
        axes[1, 0].set_ylabel("motor torque [N m]")
        for ax in axes.flat:
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize="x-small")
        fig.suptitle(f"Fig. {fig_no}: position and motor torque, {m} motion")
        fig.tight_layout()
        name = f"fig{fig_no}_{m}_time.png"
        fig.savefig(out / name, dpi=100)
        plt.close(fig)
        names.append(name)
    return names


# -- forensics ----------------------------------------------------------------------
def _lowpass_periodic(t: np.ndarray, y: np.ndarray, T: float) -> np.ndarray:
    """A first-order low-pass (time constant T) in periodic steady state over a record of whole periods."""
    if T <= 0.0:
        return y
    h = float(np.median(np.diff(t)))
    a = math.exp(-h / T)
    x = float(np.mean(y))
    out = np.empty_like(y)
    for _ in range(1 + int(math.ceil(10 * T / (h * len(y))))):  # repeat the period until the start has settled
        for k, v in enumerate(y):
            x = a * x + (1.0 - a) * v
            out[k] = x
    return out


def _phase_crossing(results: list[SineResult], level_deg: float = -45.0) -> float:
    res = [r for r in results if not r.error]
    for a, b in zip(res, res[1:]):
        if a.phase_deg >= level_deg > b.phase_deg:
            w = (a.phase_deg - level_deg) / (a.phase_deg - b.phase_deg)
            return math.exp(math.log(a.frequency) + w * (math.log(b.frequency) - math.log(a.frequency)))
    return float("nan")


def _paper_phase_crossing() -> float:
    """Where the paper's section 4.2 phases, read as a first-order lag with a delay
    (-atan(f/f_c) - 360 f tau, least squares through the three points), cross the bandwidth phase."""
    from scipy.optimize import brentq, least_squares

    f = np.array(list(paper.POSITION_RESPONSE))
    ph = np.array([p for _, p in paper.POSITION_RESPONSE.values()])

    def model(x: np.ndarray, f: np.ndarray) -> np.ndarray:
        return -np.degrees(np.arctan(f / x[0])) - 360.0 * f * x[1]

    x = least_squares(lambda x: model(x, f) - ph, [4.0, 0.005], bounds=([0.1, 0.0], [100.0, 0.1])).x
    return float(brentq(lambda g: float(model(x, np.array([g]))[0]) - paper.BANDWIDTH_PHASE_DEG, 0.01, 20.0))


def forensic_values(ssp: str, params: dict, groups: dict, m_eq22: float) -> dict:
    """The numbers behind docs/reproduction.md's paper forensics, computed from this run's parameters and results
    (the summary's ``forensics``; the report's "Forensic numbers" write them): frequencies [Hz], masses [kg],
    torques [N m], the gains."""
    from fmus.actuator.model import natural_frequencies, transmission_ratio, two_inertia
    from fmus.mechanism.dynamics import Masses, inverse_dynamics
    from fmus.mechanism.kinematics import Geometry

    from ..core.ssv import parse_ssv

    mech, ctl = _component_params(ssp, "mechanism"), {**_component_params(ssp, "controller"), **reading_gains()}
    loop = _component_params(ssp, "actuator_1")  # the drive's current loop runs in the actuators
    fn, eq22 = natural_frequencies(params), natural_frequencies({**params, "M_load": m_eq22})
    identified = resource_parameters(IDENTIFIED_SET)
    ident = {**params, **identified}
    i_R = transmission_ratio(params["p"], params["i_r"])
    rho0 = float(params["rho_0"])
    idp = inverse_dynamics(
        Geometry.from_params(mech), Masses.from_params(mech), np.full(3, rho0), np.zeros(3), np.zeros(3)
    )
    ident_t = {(r.axis, r.frequency): r for r in groups["time_ident"]}
    manuf_t = {(r.axis, r.frequency): r for r in groups["time_manuf"]}
    peak_i, peak_m = (max(d[("z", 0.4)].torque_peak) for d in (ident_t, manuf_t))
    r10 = ident_t[("z", 10.0)]
    lowpass = {}
    if r10.signals:
        for T in (0.0, 0.002, 0.005, 0.01):
            filt = _lowpass_periodic(r10.signals["time"], r10.signals["actuator_1.tau_m"], T)
            lowpass[f"{1e3 * T:g}"] = _ptp(manuf_t[("z", 10.0)]) - float(np.ptp(filt))
    return {
        "M_star_kg": float(params["M_load"]),
        "M_eq22_kg": m_eq22,
        "m_platform_kg": float(mech["m_platform"]),
        "m_leg_kg": float(mech["m_leg"]),
        "tf2_Hz": fn["TF2"],
        "fn_Hz": fn["TF1"],
        "tf2_eq22_Hz": eq22["TF2"],
        "fn_eq22_Hz": eq22["TF1"],
        "phase_45_z_Hz": _phase_crossing(groups["sweep_z"]),
        "phase_45_z_alone_Hz": _phase_crossing(groups["sweep_z_alone"]),
        "db3_z_Hz": _bandwidth(groups["sweep_z"]),
        "db3_z_alone_Hz": _bandwidth(groups["sweep_z_alone"]),
        "paper_phase_45_Hz": _paper_phase_crossing(),
        # each drive's equivalent carriage mass (J1 + J2)/i_R^2, identified and manufacturer sets [kg]
        "m_actuator_kg": sum(two_inertia(ident)) / i_R**2,
        "m_actuator_manufacturer_kg": sum(two_inertia(params)) / i_R**2,
        **{f"m_mechanism_{k}_kg": float(m) for k, m in enumerate(np.diag(idp.M), 1)},
        **{
            f"mass_{extra:g}_{what}_Hz": reading(groups[f"mass_{extra:g}"])
            for extra in EXTRA_MASS_KG
            for what, reading in (("phase_45", _phase_crossing), ("db3", _bandwidth))
        },
        # the paper's own magnitudes at 5 and 10 Hz read as a first-order lag: its -3 dB point
        **{
            f"paper_db3_from_{f:g}Hz": f / math.sqrt(1.0 / mag**2 - 1.0)
            for f, (mag, _) in paper.POSITION_RESPONSE.items()
            if f >= 5.0
        },
        "tau_c_manufacturer_Nm": float(params["tau_c"]),
        "tau_c_identified_Nm": float(identified["tau_c"]),
        "peak_difference_Nm": peak_i - peak_m,
        "peak_error": 1 - peak_m / peak_i,
        **{f"lowpass_{T}ms_Nm": v for T, v in lowpass.items()},
        **{f"{g}": float(ctl[g]) for g in ("k_v", "k_p", "k_i", "T_cur", "T_vel", "T_pos", "i_max")},
        **{f"{g}": float(loop[g]) for g in ("k_pc", "k_ic", "u_max")},
        "fit": parse_ssv(SSP_SRC / "resources" / f"{GAINS_SET}.ssv")["k_v"].source,
    }


def _forensic_lines(v: dict) -> list[str]:
    """The report's "Forensic numbers" from ``forensic_values``."""
    mass_bw = ", ".join(
        f"+{extra:g} kg: {v[f'mass_{extra:g}_phase_45_Hz']:.2f} Hz at -45 deg, {v[f'mass_{extra:g}_db3_Hz']:.2f} Hz "
        "at -3 dB"
        for extra in EXTRA_MASS_KG
    )
    lowpass = [k for k in v if k.startswith("lowpass_")]
    fc = [v[k] for k in v if k.startswith("paper_db3_from_")]
    m_total = v["m_platform_kg"] + 3 * v["m_leg_kg"]
    m_mechanism = ", ".join(f"{v[f'm_mechanism_{k}_kg']:.2f}" for k in (1, 2, 3))
    tau_m, tau_i = v["tau_c_manufacturer_Nm"], v["tau_c_identified_Nm"]
    return [
        f"- Resonances (Fig. 7, Table 1): with Table 1's M* = {v['M_star_kg']:g} kg as the moving carriage, "
        f"TF2 = sqrt(K_t/J2) lies at {v['tf2_Hz']:.0f} Hz and the free-free mode at {v['fn_Hz']:.0f} Hz; with Eq. 22's "
        f"M_load = {v['M_eq22_kg']:g} kg (platform {v['m_platform_kg']:g} kg + 3 legs x {v['m_leg_kg']:g} kg = "
        f"{m_total:.2f} kg, the MAST itself) they would lie at {v['tf2_eq22_Hz']:.0f} and {v['fn_eq22_Hz']:.0f} Hz.",
        f"- Bandwidth: phase -45 deg at {v['phase_45_z_Hz']:.2f} Hz with the MAST and "
        f"{v['phase_45_z_alone_Hz']:.2f} Hz alone (the rows); -3 dB at {v['db3_z_Hz']:.2f} and "
        f"{v['db3_z_alone_Hz']:.2f} Hz. The paper's own section 4.2 numbers: a first-order lag with a delay through "
        f"its three phases crosses -45 deg at {v['paper_phase_45_Hz']:.2f} Hz. "
        f"Each drive moves an equivalent carriage mass (J1 + J2)/i_R^2 = {v['m_actuator_kg']:.1f} kg (identified set), "
        f"the MAST adds {m_mechanism} kg along guides 1-3 at "
        f"home. Extra moving mass per drive on the z bandwidth: {mass_bw} (the P / PI cascade peaks more as the "
        "velocity loop slows: mass raises the -3 dB point and barely moves the phase). The paper's own magnitudes "
        f"read as a first-order lag put its -3 dB point at {', '.join(f'{x:.2f}' for x in fc)} Hz (from 5 and 10 Hz), "
        "not 3.5 Hz.",
        f"- Torques at 0.4 Hz: the friction at the motor is {1e3 * tau_m:.1f} mN m (Eq. 23 through the gearbox) and "
        f"{1e3 * tau_i:.1f} mN m identified; the square swing of each is twice that, so the "
        f"peak-to-peak difference is about 2 x {1e3 * (tau_i - tau_m):.1f} mN m. The peak "
        f"(offset included) reading would give {v['peak_difference_Nm']:.3f} N m and {100 * v['peak_error']:.0f} %.",
        "- Torque at 10 Hz, with the drive's torque low-pass on the measured (identified) torque, manufacturer minus "
        "measured, peak-to-peak: "
        + ("; ".join(f"T = {k.split('_')[1][:-2]} ms: {v[k]:.3f} N m" for k in lowpass) if lowpass else "(no signals)")
        + ".",
        f"- Controller: k_v = {v['k_v']:.4g} 1/s, k_p = {v['k_p']:.4g} A s/rad, k_i = "
        f"{v['k_i']:.4g} A/rad (fitted), k_pc = {v['k_pc']:.4g} V/A, k_ic = {v['k_ic']:.4g} "
        f"V/(A s), cycle times {1e6 * v['T_cur']:.0f} us / {1e3 * v['T_vel']:g} ms / "
        f"{1e3 * v['T_pos']:g} ms (current / velocity / position); limits {v['i_max']:g} A, {v['u_max']:g} V.",
        f"- Gain fit and its residual: {v['fit']}.",
    ]


def _write_report(
    out: Path,
    rows: list[Row],
    figures: list[str],
    failures: list[str],
    summary: dict,
    ssp: str,
    workers: int,
    forensics: list[str],
    limits: list[dict],
    sweep_groups: dict,
) -> None:
    s = summary
    lines = [
        "# Reproduction of the paper's results",
        "",
        f"Generated by `mast reproduce` from {s['runs']} co-simulations of `{Path(ssp).name}` "
        f"({workers} worker processes, {s['wall_time_s']:.0f} s wall time).",
        "",
        f"**{s['predictions_within']} of {s['predictions']} predictions** lie within the paper's own "
        f"simulation-vs-experiment deviation ({paper.TOLERANCE_SENTENCE}: 11 % of a magnitude, 13 % of a phase lag). "
        f"Fitted: {s['fits_within']} of {s['fits']} (the controller gains k_v, k_p, k_i were fitted to these, "
        f"`mast fit-gains`); reused: {s['reuses_within']} of {s['reuses']} (the paper gives one number per frequency "
        "for all motions; z's was fitted, so psi and theta at those frequencies check the model, they predict "
        "nothing).",
        "",
        "Conditions: sine amplitudes (not in the paper, assumed) "
        f"{1e3 * paper.AMPLITUDE['z']:g} mm in z and {math.degrees(paper.AMPLITUDE['psi']):g} deg in psi and theta; "
        "frequency responses from the steady-state harmonic after the settling periods; one parameter set for every "
        "row: the SSP's, in the reading of ssp/resources/actuator_paper_reading.ssv (Table 1's M* as the carriage) "
        "with the gains fitted in it (controller_paper_reading_fit.ssv), "
        "Sim. Ident. (J1/1.56, Coulomb friction 7.18e-2 N m) unless a row says manufacturer; the identified set stands "
        "for the measurement in the torque rows; the drive's current limit is part of every test.",
        "",
        "| quantity | kind | unit | paper | ours | difference | tolerance | within | source | note |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        mark = "yes" if r.within else "**no**"
        lines.append(
            f"| {r.claim.quantity} | {r.kind} | {r.claim.unit} | {r.claim.value:.4g} | {r.ours:.4g} | "
            f"{r.difference:+.3g} | {r.tolerance_text} | {mark} | {r.claim.source} | {r.note} |"
        )
    lines += [
        "",
        "## Where a test touches a limit",
        "",
        "Largest current command in steady state against the drive's limit (drive.ssv `i_max`).",
        "",
        "| variant | motion | frequency [Hz] | peak current [A] | limit [A] | on the limit |",
        "|---|---|---|---|---|---|",
    ]
    for t in limits:
        lines.append(
            f"| {t['variant']} | {t['motion']} | {t['frequency_Hz']:g} | {t['i_peak_A']:.2f} | {t['i_max_A']:g} | "
            f"{'**yes**' if t['at_limit'] else 'no'} |"
        )
    sweeps = _sweep_limits(sweep_groups, limits[0]["i_max_A"]) if limits else []
    lines += [
        "",
        "Sweep tests on the current limit (Figs. 8-10; their response is the saturated one): "
        + ("; ".join(sweeps) if sweeps else "none")
        + ".",
    ]
    lines += ["", "## Forensic numbers (docs/reproduction.md explains them)", ""] + forensics
    if failures:
        lines += ["", "## Runs that failed", ""] + [f"- {f}" for f in failures]
    lines += ["", "## Figures", ""] + [f"![{name}]({name})" for name in figures]
    (out / "report.md").write_text("\n".join(lines) + "\n")
