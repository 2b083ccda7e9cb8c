"""Outputs of the diagnosis: the augmented parameter set and an SSP that binds it, the figures, report.md."""

from __future__ import annotations

import math
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Mapping, Optional, Sequence

import numpy as np

from ..core import ssd, ssv
from .resimulation import Model, Point

if TYPE_CHECKING:
    from .options import Options


def jsonable(x):
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, Path):
        return str(x)
    return x


def write_model(
    opt: Options, changes: Mapping[str, float], named: Sequence[dict], nominal: Mapping, model_over: Mapping
) -> dict:
    from .effects import AXIS_OF, CONTROLLER_PARAMETERS, axis_values

    # a value the plan does not determine (a phase-free effect named present, phase_free.value_determined) is not
    # written as a number: the augmented model leaves that parameter at its nominal value
    undetermined = {
        p: {
            "named_value": float(v),
            "ci95": eff["evidence"]["phase_free"]["ci95"],
            "why": eff["evidence"]["phase_free"]["value_not_determined_because"],
        }
        for eff in named
        if not eff["evidence"].get("phase_free", {}).get("value_determined", True)
        for p, v in eff["parameters"].items()
    }
    changes = {k: v for k, v in changes.items() if k not in undetermined}
    drive = {k: v for k, v in changes.items() if k in CONTROLLER_PARAMETERS}
    shared = {k: v for k, v in changes.items() if k not in drive and k not in AXIS_OF}
    values = {**{k: v for k, v in model_over.items()}, **shared}
    # per-axis increments: the value of that actuator, in a parameter set of its own, bound after the shared one
    axes = {
        j: {
            base: v
            for base, v in axis_values(
                {**shared, **{k: v for k, v in changes.items() if k in AXIS_OF}}, nominal, j
            ).items()
            if base not in shared or v != shared[base]
        }
        for j in sorted({AXIS_OF[k][1] for k in nominal if k in AXIS_OF})  # the system's drives (0-based)
    }
    axes = {j: a for j, a in axes.items() if a}
    why = {}
    for eff in named:
        for p, v in eff["parameters"].items():
            u = eff["uncertainty"].get(p, {}).get("std")
            why[p] = (
                f"mast diagnose: {eff['effect']}; fitted {v:.6g} (std {u:.2g})"
                if u is not None
                else f"mast diagnose: {eff['effect']}; fitted {v:.6g}"
            )
    from fmus.actuator.model import PARAMETERS
    from fmus.controller.model import CASCADE_PARAMETERS, DRIVE_PARAMETERS

    units = {p.name: p.unit for p in PARAMETERS}
    ssv_path = ssv.write(
        opt.out / "actuator_diagnosed.ssv",
        ssv.parameter_set(
            "actuator_diagnosed",
            values,
            units,
            {name: why.get(name, f"nominal model ({opt.model})") for name in values},
            f"Written by mast diagnose from {Path(opt.measured).name}: the nominal model "
            f"({opt.model or 'SSP bindings'}) "
            "plus the named effects; bind it after the actuators' other parameter sets (MAST_diagnosed.ssp does).",
        ),
    )
    out = {
        "parameter_set": str(ssv_path),
        "values": dict(values),
        "use": "bind resources/actuator_diagnosed.ssv after the other parameter sets of every actuator_k "
        "(MAST_diagnosed.ssp does that); compare the lab's torque with actuator_k.tau_meas",
    }
    if undetermined:
        out["not_determined"] = undetermined  # named present, left at the nominal value: the plan does not pin it
    if drive:  # a controller-side effect: the drive's gains, a parameter set of the controller component
        ssv.write(
            opt.out / "controller_diagnosed.ssv",
            ssv.parameter_set(
                "controller_diagnosed",
                drive,
                {p.name: p.unit for p in DRIVE_PARAMETERS + CASCADE_PARAMETERS},
                {name: why.get(name, "mast diagnose") for name in drive},
                f"Written by mast diagnose from {Path(opt.measured).name}: the drive parameters the data show; bind it "
                "after the controller's other parameter sets.",
            ),
        )
        out["controller_parameter_set"] = str(opt.out / "controller_diagnosed.ssv")
        out["controller_values"] = dict(drive)
    for j, a in axes.items():
        ssv.write(
            opt.out / f"actuator_{j + 1}_diagnosed.ssv",
            ssv.parameter_set(
                f"actuator_{j + 1}_diagnosed",
                a,
                units,
                {name: f"mast diagnose: {name} of actuator {j + 1}" for name in a},
                f"Written by mast diagnose: actuator {j + 1} only (an effect on one axis); bind it after "
                "actuator_diagnosed.ssv.",
            ),
        )
        out.setdefault("axis_values", {})[f"actuator_{j + 1}"] = dict(a)
    src = Path(opt.ssp)
    if src.suffix == ".ssp" and src.exists():
        dst = opt.out / "MAST_diagnosed.ssp"
        with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
            for item in zin.infolist():
                data = zin.read(item.filename)
                if item.filename == "SystemStructure.ssd":
                    document = ssd.read(data, f"{src} (entry {item.filename})")
                    document.system.bind("resources/actuator_diagnosed.ssv", lambda name: name.startswith("actuator_"))
                    if drive:
                        document.system.bind("resources/controller_diagnosed.ssv", lambda name: name == "controller")
                    for j in axes:
                        document.system.bind(
                            f"resources/actuator_{j + 1}_diagnosed.ssv", lambda name, j=j: name == f"actuator_{j + 1}"
                        )
                    data = document.to_bytes()
                zout.writestr(item, data)
            zout.write(ssv_path, "resources/actuator_diagnosed.ssv")
            if drive:
                zout.write(opt.out / "controller_diagnosed.ssv", "resources/controller_diagnosed.ssv")
            for j in axes:
                zout.write(opt.out / f"actuator_{j + 1}_diagnosed.ssv", f"resources/actuator_{j + 1}_diagnosed.ssv")
        out["ssp"] = str(dst)
    return out


def plot_figures(
    out: Path,
    model: Model,
    prepared,
    names,
    before: Point,
    after: Point,
    sigma: float,
    roles,
    unexplained: bool,
    phase_free: Optional[dict],
) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs = {}
    # 1. measured vs simulated, before and after: lowest, a held-out, highest frequency
    order = sorted(names, key=lambda n: (prepared[n].test.frequency or 0.0, n))
    show = list(dict.fromkeys([order[0]] + [n for n in order if roles[n] == "held-out"][:1] + [order[-1]]))
    # the motor whose torque the nominal model misses most on these tests (an effect on one axis shows there)
    k = int(np.argmax(sum(((prepared[n].y - before.obs[n]) ** 2).sum(axis=0) for n in show)))
    fig, axes = plt.subplots(len(show), 1, figsize=(9, 2.6 * len(show)), squeeze=False)
    for ax, n in zip(axes[:, 0], show):
        p = prepared[n]
        f = p.test.frequency
        keep = p.t >= (p.t[-1] - min(2.0 / f, p.t[-1] - p.t[0]) if f else p.t[0])
        ax.plot(p.t[keep], p.y[keep, k], color="0.55", lw=0.8, label="measured")
        ax.plot(p.t[keep], before.obs[n][keep, k], color="tab:red", lw=1.2, label="nominal model")
        ax.plot(p.t[keep], after.obs[n][keep, k], color="tab:blue", lw=1.2, ls="--", label="diagnosed model")
        ax.set_title(f"{p.test.label()} ({roles[n]}), motor {k + 1}", fontsize=9)
        ax.set_ylabel("tau_m [N m]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(out / "fig_time.png", dpi=110)
    plt.close(fig)
    figs["time"] = "fig_time.png"

    # 2. residual against velocity and acceleration, before and after
    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharey="row")
    for row, (pt, title) in enumerate(((before, "nominal model"), (after, "diagnosed model"))):
        for n in names:
            w, a, _ = model.signals(pt, n)
            r = prepared[n].y - pt.obs[n]
            step = max(1, r.shape[0] // 400)
            axes[row, 0].plot(
                w[::step].ravel(), r[::step].ravel(), ".", ms=1.5, alpha=0.5, label=prepared[n].test.label()
            )
            axes[row, 1].plot(a[::step].ravel(), r[::step].ravel(), ".", ms=1.5, alpha=0.5)
        for c in (0, 1):
            axes[row, c].axhline(2 * sigma, color="k", lw=0.6, ls=":")
            axes[row, c].axhline(-2 * sigma, color="k", lw=0.6, ls=":")
            axes[row, c].grid(alpha=0.3)
        axes[row, 0].set_ylabel(f"torque residual [N m]\n{title}")
    axes[1, 0].set_xlabel("guide speed at the motor shaft omega_N [rad/s]")
    axes[1, 1].set_xlabel("guide acceleration [rad/s^2]")
    axes[0, 0].legend(fontsize=7, markerscale=6, loc="best")
    fig.suptitle(
        "Residual (measured - simulated) against velocity and acceleration; dotted: +-2 sigma noise", fontsize=10
    )
    fig.tight_layout()
    fig.savefig(out / "fig_residual_signals.png", dpi=110)
    plt.close(fig)
    figs["residual_signals"] = "fig_residual_signals.png"

    # 3. residual amplitude against frequency
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for pt, color, label in ((before, "tab:red", "nominal"), (after, "tab:blue", "diagnosed")):
        for role, marker in (("training", "o"), ("held-out", "s")):
            ns = [n for n in names if roles[n] == role and prepared[n].test.frequency]
            if not ns:
                continue
            f = [prepared[n].test.frequency for n in ns]
            rms = [float(np.sqrt(np.mean((prepared[n].y - pt.obs[n]) ** 2))) for n in ns]
            ax.loglog(
                f, rms, marker, color=color, mfc=color if role == "training" else "none", label=f"{label}, {role}"
            )
    ax.axhline(sigma, color="k", ls="--", lw=0.8, label="noise floor")
    ax.set_xlabel("test frequency [Hz]")
    ax.set_ylabel("torque residual RMS [N m]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "fig_residual_frequency.png", dpi=110)
    plt.close(fig)
    figs["residual_frequency"] = "fig_residual_frequency.png"

    if phase_free:
        fig, axes = plt.subplots(1, len(names), figsize=(3.2 * len(names), 3.4), squeeze=False)
        for ax, n in zip(axes[0], names):
            bp, bands = phase_free["band_powers_Nm_squared"][n], phase_free["bands_Hz"][n]
            x = np.arange(len(bands))
            for key, style, label in (
                ("measured", "ko", "measured"),
                ("without", "s--", "without it"),
                ("with", "o-", "with it (ensemble)"),
            ):
                ax.semilogy(x, np.sqrt(bp[key]) * 1e3, style, ms=4, lw=1, label=label)
            ax.set_xticks(x, [f"{lo:g}-{hi:g}" for lo, hi in bands], fontsize=7)
            ax.set_title(f"{prepared[n].test.label()} ({roles[n]})", fontsize=8)
            ax.set_xlabel("band [Hz]", fontsize=8)
            ax.grid(alpha=0.3, which="both")
        axes[0, 0].set_ylabel("residual RMS in the band [mN m]")
        axes[0, 0].legend(fontsize=7)
        fig.suptitle(
            f"Phase-free score of {phase_free['parameter']} = {phase_free['value']:.4g}: band powers of the "
            "residual against the nominal model",
            fontsize=9,
        )
        fig.tight_layout()
        fig.savefig(out / "fig_phase_free.png", dpi=110)
        plt.close(fig)
        figs["phase_free"] = "fig_phase_free.png"

    if unexplained:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        for n in names:
            _, _, rho = model.signals(after, n)
            r = prepared[n].y - after.obs[n]
            step = max(1, r.shape[0] // 600)
            start = prepared[n].test.rho_cmd[0]
            axes[0].plot(
                (rho - start)[::step].ravel() * 1e3,
                r[::step].ravel(),
                ".",
                ms=1.5,
                alpha=0.5,
                label=prepared[n].test.label(),
            )
            dt = prepared[n].test.sample_time
            spec = np.abs(np.fft.rfft(r - r.mean(axis=0), axis=0)).mean(axis=1) / r.shape[0]
            fr = np.fft.rfftfreq(r.shape[0], dt)
            axes[1].loglog(fr[1:], spec[1:], lw=0.6, label=prepared[n].test.label())
        axes[0].set_xlabel("carriage position from the test's start [mm]")
        axes[0].set_ylabel("torque residual [N m]")
        axes[1].set_xlabel("frequency [Hz]")
        axes[1].set_ylabel("residual spectrum [N m]")
        axes[0].legend(fontsize=7, markerscale=6)
        for ax in axes:
            ax.grid(alpha=0.3)
        fig.suptitle("Unexplained residual of the diagnosed model: against position and its spectrum", fontsize=10)
        fig.tight_layout()
        fig.savefig(out / "fig_unexplained.png", dpi=110)
        plt.close(fig)
        figs["unexplained"] = "fig_unexplained.png"
    return figs


def write_report(out: Path, doc: dict, figs: Mapping[str, str]) -> None:
    v = doc["verdict"]
    lines = [
        f"# Diagnosis of {Path(doc['measured']).name}",
        "",
        f"Nominal model: {doc['model']} ({Path(doc['ssp']).name}). Torque noise floor: "
        f"{1e3 * doc['noise_floor']['torque_std_Nm']:.3g} mN m ({doc['noise_floor']['method']}).",
        "",
        f"**Verdict: {v['status']}.** {v['text']}.",
        "",
    ]
    lines += ["## Named effects", ""]
    if doc["named_effects"]:
        lines += [
            "| effect | parameter | nominal | fitted | std | evidence (re-simulated when added) |",
            "|---|---|---|---|---|---|",
        ]
        for e in doc["named_effects"]:
            ev = e["evidence"]
            wa = ev.get("when_added")
            text = (
                f"dBIC {wa['delta_bic_training']:+.0f}, held-out RSS {wa['held_out_rss_change_percent']:+.0f} %"
                if wa and wa.get("held_out_rss_change_percent") is not None
                else f"phase-free dBIC {wa['delta_bic']:+.0f}, leave-one-test-out deviance "
                f"{wa['cross_validated_deviance_change']:+.0f}"
                if wa and "cross_validated_deviance_change" in wa
                else f"dBIC {wa['delta_bic_training']:+.0f}"
                if wa
                else ""
            )
            for p, val in e["parameters"].items():
                std = e["uncertainty"][p]["std"]
                std_text = f"{std:.2g}" if std is not None and math.isfinite(std) else "-"
                pf = ev.get("phase_free")
                val_text = (
                    f"{val:.5g}"
                    if not pf or pf["value_determined"]
                    else f"not determined ({pf['ci95'][0]:.3g} to {pf['ci95'][1]:.3g}; not in the augmented model)"
                )
                lines.append(f"| {e['effect']} | `{p}` | {e['nominal'][p]:.5g} | {val_text} | {std_text} | {text} |")
            for alt in ev.get("alternatives", []):
                if "equivalent_value" in alt and alt["equivalent_value"] is not None:
                    lines.append(
                        f"| (or) {alt['effect']} | `{alt['parameter']}` | | {alt['equivalent_value']:.5g} | | "
                        f"{alt['how']}: dBIC {alt['delta_bic_band']:+.1f} |"
                    )
                elif "parameters" in alt:
                    vals = ", ".join(f"`{k}` = {v:.5g}" for k, v in alt["parameters"].items())
                    lines.append(
                        f"| (or) {alt['effect']} | {vals} | | | | {alt['how']}: dBIC full band "
                        f"{alt['delta_bic_full_band']:+.0f}, in the band {alt['delta_bic_band']:+.1f}: "
                        f"{alt['note']} |"
                    )
            if "filter_or_delay" in ev and "text" in ev["filter_or_delay"]:  # both forms fitted (lag_form_check)
                fd = ev["filter_or_delay"]
                lines.append(
                    f"| (delay or filter) | `{fd['delay_parameter']}`, `{fd['filter_parameter']}` | | "
                    f"{fd['delay_meas']:.4g}, {fd['T_meas']:.4g} | | {fd['text']}: dBIC (delay - filter) "
                    f"training {fd['delta_bic_delay_vs_filter']:+.0f}, held-out "
                    f"{fd['held_out_deviance_delay_vs_filter']:+.0f} (full band) |"
                )
            ho = ev.get("held_out_evidence")
            if ho:
                per = ho.get("rss_change_percent_per_test") or {}
                lines.append(
                    f"| (held-out evidence) | | | | | {', '.join(ho['tests']) or 'none'}"
                    + (": " + ", ".join(f"{n} {v:+.0f} %" for n, v in per.items() if v is not None) if per else "")
                    + f" ({ho['how']}) |"
                )
        lines.append("")
    else:
        lines += ["None.", ""]
    for e in doc["named_effects"]:
        pf = e["evidence"].get("phase_free")
        if not pf:
            continue
        lo, hi = pf["ci95"]
        lines += [
            "## Phase-free score",
            "",
            f"{e['effect']} makes the loop hunt, which no simulation reproduces sample by sample; it was scored by "
            f"the band powers of the torque residual against ensembles of re-simulations (commands perturbed far "
            f"below their precision; the value's score pools the {pf['pooled_realisations']} realisations of the "
            f"values within {100 * (pf['pool_ratio'] - 1):.0f} % of it), noise {1e3 * pf['noise_std_Nm']:.3g} mN m "
            f"(profiled). `{pf['parameter']}` = {pf['value']:.4g} (95 %: {lo:.4g} to {hi:.4g}); the scan on all "
            f"tests chose {pf['scan_value']:.4g} (dBIC {pf['delta_bic']:+.0f}), and leave-one-test-out "
            f"confirmed it (deviance {pf['cross_validated_deviance_change']:+.0f}: every test predicted at the "
            "scan value best on the others)."
            + (
                ""
                if pf["value_determined"]
                else f" Its value is not determined on this plan ({'; '.join(pf['value_not_determined_because'])}): "
                f"it is present, `{pf['parameter']}` is not written into the augmented model (it keeps the nominal "
                f"value), and {lo:.4g} to {hi:.4g} is its interval on the tests it is fitted on"
                + (f" ({', '.join(pf['fitted_on'])})" if pf.get("not_reproduced") else "")
                + "."
            )
            + (
                f" {', '.join(pf['not_reproduced'])} hunts in a quieter regime than its re-simulations visit: a "
                "run of a loop that hunts is one realisation, which regime it falls into depends on the commands' "
                f"last digits, so it is reported, not fitted: the value is fitted on {', '.join(pf['fitted_on'])} "
                "(docs/diagnose.md)."
                if pf.get("not_reproduced")
                else ""
            ),
            "",
            "| test | deviance without it | with it | floor |",
            "|---|---|---|---|",
        ]
        dev = pf["deviance_per_test"]
        lines += [
            f"| {n} | {dev['before'][n]:.1f} | {dev['after'][n]:.1f} | {pf['floor_per_test'][n]:.1f} |"
            for n in dev["after"]
        ]
        lines.append("")
    if doc.get("split"):
        lines += [f"Split: {doc['split']['how']}.", ""]
    cv = doc.get("cross_validation") or {}
    if cv.get("folds"):
        lines += _cross_validation_lines(cv)
    lines += [
        "## Gap per test (torque NRMSE %, lower is better)",
        "",
        "| test | role | before | after | noise floor | tracking error NRMSE % before / after |",
        "|---|---|---|---|---|---|",
    ]
    for t in doc["tests"]:
        g = doc["gap"][t["name"]]
        b, a = g["before"], g["after"]
        lines.append(
            f"| {t['label']} | {g['role']} | {b['torque_nrmse_percent']:.1f} | {a['torque_nrmse_percent']:.1f} | "
            f"{b['torque_floor_percent']:.1f} | {b['tracking_error_nrmse_percent']:.1f} / "
            f"{a['tracking_error_nrmse_percent']:.1f} |"
        )
    lines += ["", "## Where the nominal model's residual concentrates", ""]
    for t in doc["tests"]:
        lb = t["localise_before"]
        lines.append(f"- {t['label']}: RMS {lb['rms_over_noise']:.1f} x noise; {lb['summary']}")
    for motion, tr in doc["frequency_trend"].items():
        if tr["log_slope_before"] is not None:
            lines.append(
                f"- {motion} tests: residual at the test frequency {tr['reading']} "
                f"(log-log slope {tr['log_slope_before']:.2f})"
            )
    lines.append("")
    if doc["unexplained"]:
        u = doc["unexplained"]
        lines += ["## Unexplained residual", "", u["text"], ""]
        lines += [f"- {n}: {w}" for n, w in u["where"].items()]
        lines += ["", "| candidate | dBIC | held-out RSS change % | rejected because |", "|---|---|---|---|"]
        for c in u["candidates_tried"]:
            ho, dbic = c["held_out_rss_change_percent"], c["delta_bic"]
            lines.append(
                f"| {c['candidate']} | {'-' if dbic is None else f'{dbic:+.1f}'} | "
                f"{'-' if ho is None else f'{ho:+.1f}'} | {c['rejected_because']} |"
            )
        lines.append("")
    hints = (doc["unexplained"] or {}).get("hints") or doc["verdict"].get("hints")
    if hints:
        lines += [
            "Hints, not names (accepted by the search, but they may only stand in for a cause outside the library):",
            "",
        ]
        lines += [
            f"- {h['effect']} ("
            + ", ".join(f"{p} = {v:.5g}, nominal {h['nominal'][p]:.5g}" for p, v in h["parameters"].items())
            + f"): {h['why_not_named']}"
            for h in hints
        ]
        lines.append("")
    lines += ["## Figures", ""]
    captions = {
        "time": "Measured and simulated motor torque, before and after",
        "residual_signals": "Residual against velocity and acceleration",
        "residual_frequency": "Residual amplitude against test frequency",
        "unexplained": "The residual no candidate explains",
        "phase_free": "Band powers of the residual: measured, and predicted with and without the effect",
    }
    for k, f in figs.items():
        lines += [f"![{captions[k]}]({f})", ""]
    am = doc["augmented_model"]
    lines += ["## The augmented model", "", f"Parameter set: `{Path(am['parameter_set']).name}` ({am['use']}).", ""]
    if am.get("ssp"):
        lines += [f"Ready to run: `mast run {Path(am['ssp']).name} ...` (records `actuator_k.tau_meas`).", ""]
    lines += [
        "## Steps",
        "",
        "| how | from | to | dBIC training | held-out RSS % | accepted |",
        "|---|---|---|---|---|---|",
    ]
    for st in doc["steps"]:
        dbic = st.get("delta_bic_training", st.get("delta_bic", st.get("delta_bic_full_band")))
        ho = st.get("held_out_rss_change_percent")
        lines.append(
            f"| {st['how']} | {', '.join(st['from']) or 'nominal'} | "
            f"{', '.join(st['to']) if isinstance(st['to'], list) else st['to']} | "
            f"{dbic:+.0f} | {ho:+.1f} | {st['accepted']} |"
            if dbic is not None and ho is not None
            else f"| {st['how']} | {', '.join(st['from']) or 'nominal'} | "
            f"{', '.join(st['to']) if isinstance(st['to'], list) else st['to']} | "
            f"{'' if dbic is None else f'{dbic:+.0f}'} | | {st['accepted']} |"
        )
    lines.append("")
    unmet = {k: p for k, p in doc.get("identifiability", {}).items() if not p["plan_meets"]}
    if unmet:
        lines += [
            "## What this test plan cannot tell",
            "",
            "An effect below may be missed or confused with another: the plan does not excite what it needs "
            "(docs/diagnose.md, identifiability table).",
            "",
            "| effect | the plan must contain | here |",
            "|---|---|---|",
        ]
        lines += [f"| {k} | {p['requires']} | {p['why_not']} |" for k, p in unmet.items()]
        lines.append("")
    unsplit = {
        k: p for k, p in doc.get("identifiability", {}).items() if p["plan_meets"] and not p.get("split_meets", True)
    }
    if unsplit:
        lines += [
            "## What this split cannot check (the plan can)",
            "",
            "The tests' roles leave no training or no held-out test of what these effects need; another split "
            "(`--holdout`) can check them.",
            "",
            "| effect | the split must contain | here |",
            "|---|---|---|",
        ]
        lines += [f"| {k} | {p['requires']} | {p['split_why_not']} |" for k, p in unsplit.items()]
        lines.append("")
    if doc.get("failed_simulations"):
        lines += [
            "## Trial simulations that failed",
            "",
            "Each is information (those values are wrong: the proposal refuted, the step shrunk), not the end "
            "of the diagnosis.",
            "",
            "| where | parameters | error |",
            "|---|---|---|",
        ]
        lines += [
            f"| {f['where']} | "
            + ", ".join(f"{k} = {v:.5g}" for k, v in f["parameters"].items())
            + f" | {f['error'][:160]} |"
            for f in doc["failed_simulations"]
        ]
        lines.append("")
    tm = doc["timing"]
    lines += [
        "## Timing",
        "",
        f"{tm['wall_s']} s wall ({tm['simulations']} test simulations, {tm['simulation_wall_s']} s "
        f"in simulation, {tm['workers']} workers, direct composition: {tm['direct']}).",
        "",
    ]
    (out / "report.md").write_text("\n".join(lines))


def _cross_validation_lines(cv: Mapping) -> list[str]:
    """report.md's "Cross-validation" section: per fold the held-out residual (band) with the selection refitted on
    the fold's training tests and without each member, then per effect the sums and the decision."""
    keys = list(cv["effects"])
    lines = [
        "## Cross-validation",
        "",
        f"Every test held out once and trained on in the other folds ({cv['how']}; {cv['simulations']} test "
        f"simulations, {cv['wall_s']:g} s). Held-out residual sum of squares in the band [N^2 m^2] with the "
        "selection, and the change without each effect (a fold whose training tests cannot identify an effect "
        "does not judge it: -):",
        "",
        "| held out | refitted on the others | with the selection | " + " | ".join(f"without {k}" for k in keys) + " |",
        "|---|---|---|" + "---|" * len(keys),
    ]
    for f in cv["folds"]:
        w = f["with"]
        cells = []
        for k in keys:
            wo = f["without"].get(k)
            cells.append(
                "-"
                if k not in f["checks"]
                else "does not simulate"
                if wo is None
                else f"{wo['band_rss']:.3g} ({100 * (wo['band_rss'] / w['band_rss'] - 1):+.0f} %)"
            )
        values = ", ".join(f"`{p}` {v:.4g}" for p, v in f["values"].items())
        lines.append(f"| {', '.join(f['held_out'])} | {values} | {w['band_rss']:.3g} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "| effect | folds judging it | held-out RSS with / without | needed | named by the folds |",
        "|---|---|---|---|---|",
    ]
    for k, v in cv["effects"].items():
        if not v["folds"]:
            lines.append(f"| {k} | none | | | {v['note']} |")
            continue
        lines.append(
            f"| {k} | {len(v['folds'])} | {v['held_out_rss_with']:.3g} / {v['held_out_rss_without']:.3g} | "
            f"{v['needed']:.3g} | {'yes' if v['confirmed'] else 'no: ' + v.get('note', 'removed')} |"
        )
    if "lag_form" in cv:
        lf = cv["lag_form"]
        lines.append(
            f"\nDelay or filter over {len(lf['folds'])} folds: held-out deviance (delay - filter, full band) "
            f"{lf['held_out_deviance_delay_vs_filter']:+.0f}: {lf['choice']}."
        )
    return lines + [""]
