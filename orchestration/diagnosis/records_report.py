"""Outputs of `mast diagnose` on a record (records.py): the augmented parameter set and SSP, figures, report.md."""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Sequence

import numpy as np

from ..core import ssd, ssv
from .axis_model import AxisModel, Case, Diagnosis, Point


def write_outputs(
    opt,
    doc: dict,
    component: str,
    model: "AxisModel",
    cases: Sequence["Case"],
    before: "Point",
    after: "Point",
    diag: "Diagnosis",
) -> dict:
    from fmus.actuator.load_axis import LOAD_AXIS_PARAMETERS

    units = {p.name: p.unit for p in LOAD_AXIS_PARAMETERS}
    named = {p: e for e in doc["named_effects"] for p in e["parameters"]}
    why = {}
    for p, v in doc["values"].items():
        if p in named:
            std = named[p]["uncertainty"][p]["std"] if named[p]["uncertainty"][p] else None
            why[p] = f"mast diagnose: {named[p]['effect']}; fitted {v:.6g}" + (f" (std {std:.2g})" if std else "")
        else:
            why[p] = f"nominal model ({doc['model']}): not named by the diagnosis"
    name = f"{component}_diagnosed"
    ssv_path = ssv.write(
        opt.out / f"{name}.ssv",
        ssv.parameter_set(
            name,
            doc["values"],
            units,
            why,
            f"Written by mast diagnose from {Path(opt.measured).name}: the nominal model "
            f"({doc['model']}) plus the named effects; bind it after the other parameter sets of '{component}' (the "
            "SSP "
            "next to it does).",
        ),
    )
    out = {
        "parameter_set": str(ssv_path),
        "values": dict(doc["values"]),
        "use": f"bind resources/{name}.ssv after the other parameter sets of '{component}'",
    }
    src = Path(opt.ssp)
    if src.suffix == ".ssp" and src.exists():
        dst = opt.out / f"{src.stem}_diagnosed.ssp"
        with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
            for item in zin.infolist():
                data = zin.read(item.filename)
                if item.filename == "SystemStructure.ssd":
                    document = ssd.read(data, f"{src} (entry {item.filename})")
                    document.system.bind(f"resources/{name}.ssv", lambda n: n == component)
                    data = document.to_bytes()
                zout.writestr(item, data)
            zout.write(ssv_path, f"resources/{name}.ssv")
        out["ssp"] = str(dst)
    figures = plot(opt.out, model, cases, before, after, diag, doc) if getattr(opt, "figures", True) else {}
    write_report(opt.out, doc, figures)
    return out


def plot(
    out: Path,
    model: "AxisModel",
    cases: Sequence["Case"],
    before: "Point",
    after: "Point",
    diag: "Diagnosis",
    doc: dict,
) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs = {}
    c = cases[0]
    s = c.efforts[0]
    rec = c.record
    t = rec.time
    y = rec.values[s]
    unit = rec.specs[s].unit
    # 1. the effort, measured and simulated, and the residual before and after
    fig, ax = plt.subplots(3, 1, figsize=(11, 7.5), sharex=True)
    ax[0].plot(t, y, lw=0.7, label="measured")
    ax[0].plot(t, before.sims[c.name][s], lw=0.7, label="nominal model")
    ax[0].plot(t, after.sims[c.name][s], lw=0.7, label="diagnosed model")
    ax[0].set_ylabel(f"{s} [{unit}]")
    ax[0].legend(fontsize=7, loc="upper right")
    ax[1].plot(t, before.residual(c, s), lw=0.6, color="C1", label="measured - nominal")
    ax[1].plot(t, after.residual(c, s), lw=0.6, color="C2", label="measured - diagnosed")
    ax[1].set_ylabel(f"residual [{unit}]")
    ax[1].legend(fontsize=7, loc="upper right")
    q = rec.values[rec.of_kind("position")[0].name] if rec.of_kind("position") else None
    if q is not None:
        ax[2].plot(t, q, lw=0.8, color="k")
        ax[2].set_ylabel("position [m]")
    for a in ax:
        if c.held.any():
            a.axvspan(t[c.held][0], t[c.held][-1], color="0.9", zorder=-1)
    ax[2].set_xlabel("time [s] (grey: held out)")
    fig.suptitle(f"{doc['machine'][:90]}: {s} before and after the diagnosis", fontsize=9)
    fig.tight_layout()
    figs["residual"] = "fig_residual.png"
    fig.savefig(out / figs["residual"], dpi=110)
    plt.close(fig)
    # 2. the friction map: measured force minus the fitted inertia and offset, against the velocity
    v, a = model.motion(after, c)
    vals = doc["values"]
    ff = y - vals["M"] * a - vals["F_offset"]
    plateau = np.abs(a) < 0.05 * np.abs(a).max()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(
        v[plateau],
        ff[plateau],
        ".",
        ms=1.5,
        alpha=0.4,
        color="0.3",
        label="measured - M q'' - offset (|q''| < 5 % of its peak)",
    )
    vv = np.linspace(v.min(), v.max(), 400)
    from fmus.actuator.load_axis import load_friction

    ax.plot(
        vv,
        load_friction(vv, vals["F_c"], vals["F_v"], vals["dF_c"], vals["dF_v"]),
        color="C2",
        label="diagnosed friction",
    )
    sym = doc.get("symmetric_model") or {}
    if sym.get("values"):
        sv = {**vals, **sym["values"]}
        shift = sv.get("F_offset", 0.0) - vals["F_offset"]  # the same offset subtracted from the points
        ax.plot(
            vv,
            load_friction(vv, sv.get("F_c", 0.0), sv.get("F_v", 0.0)) + shift * (vv != 0),
            "--",
            color="C1",
            label="symmetric model (stage 'name'), its offset relative to the diagnosed one",
        )
    ax.set_xlabel("simulated velocity [m/s]")
    ax.set_ylabel(f"friction [{unit}]")
    ax.legend(fontsize=7)
    fig.tight_layout()
    figs["friction"] = "fig_friction.png"
    fig.savefig(out / figs["friction"], dpi=110)
    plt.close(fig)
    return figs


def _fmt(x, digits: int = 4) -> str:
    return "-" if x is None else f"{x:.{digits}g}"


def write_report(out: Path, doc: dict, figs: dict) -> None:
    lines = [
        f"# Diagnosis of {doc['machine']}",
        "",
        f"Model `{doc['ssp']}` (component `{doc['component']}`, nominal: {doc['model']}), record "
        f"`{doc['measured']}`. Held out: {doc['held_out']}.",
        "",
        f"**Verdict: {doc['verdict']['status']}.** {doc['verdict']['text']}",
        "",
        "## Named effects",
        "",
        "| effect | parameter | nominal | fitted | std |",
        "|---|---|---|---|---|",
    ]
    for e in doc["named_effects"]:
        for p, v in e["parameters"].items():
            std = (e["uncertainty"][p] or {}).get("std")
            lines.append(f"| {e['effect']} | `{p}` | {_fmt(e['nominal'][p])} | {_fmt(v, 6)} | {_fmt(std, 2)} |")
    lines += ["", "Friction per direction (positive / negative velocity):", ""]
    for k, a in doc["asymmetry"].items():
        lines.append(
            f"- {k}: {_fmt(a['positive_velocity'], 5)} / {_fmt(a['negative_velocity'], 5)} "
            f"({'asymmetric: named' if a['asymmetric'] else 'symmetric (no asymmetry named)'})"
        )
    sym = doc.get("symmetric_model")
    if sym:
        lines += [
            "",
            "## The symmetric model (stage 'name', before the asymmetries were tried)",
            "",
            ", ".join(f"`{p}` = {_fmt(v, 6)}" for p, v in sym["values"].items()),
        ]
    lines += [
        "",
        "## The gap",
        "",
        "| test | signal | part | relative error % before | after | fit % before | after |",
        "|---|---|---|---|---|---|---|",
    ]
    for test, table in doc["gap"]["after"].items():
        for sig, row in table.items():
            for part in ("training", "held-out", "whole"):
                if part in row:
                    b = doc["gap"]["before"][test][sig][part]
                    lines.append(
                        f"| {test} | {sig} ({row['kind']}) | {part} | {_fmt(b['relative_error_pct'])} | "
                        f"{_fmt(row[part]['relative_error_pct'])} | {_fmt(b['fit_pct'])} | "
                        f"{_fmt(row[part]['fit_pct'])} |"
                    )
    nf = doc["noise_floor"]
    lines += [
        "",
        f"Noise floor of the effort: {_fmt(nf['effort_std'])} (third differences), i.e. "
        + ", ".join(f"{k} {_fmt(v, 3)} %" for k, v in nf["relative_error_pct"].items())
        + " relative error.",
        "",
        "## Where the residual is",
        "",
    ]
    for when in ("before", "after"):
        for k, loc in doc["localise"][when].items():
            lines.append(
                f"- {when}, {k}: {loc['summary']} (correlation: "
                + ", ".join(f"{n} {v:+.2f}" for n, v in loc["correlation"].items())
                + ")"
            )
    lines += ["", "## Steps", ""]
    for st in doc["steps"]:
        txt = f"- {st['stage']}: regression proposes {', '.join(st['proposed']) or 'nothing'}"
        if "confirmed" in st:
            held = (
                f"held-out band RSS {st['held_out_rss_change_percent']:+.1f} %: "
                if st["held_out_rss_change_percent"] is not None
                else ""
            )
            txt += (
                f"; fitted by re-simulation ({st['fit']['steps']} Gauss-Newton step(s)): "
                f"dBIC {st['delta_bic_training']:.1f}, {held}{'confirmed' if st['confirmed'] else 'refused'}"
            )
        lines.append(txt)
    for key, title in (("residual", "Effort and residual"), ("friction", "Friction against velocity")):
        if key in figs:
            lines += ["", f"## {title}", "", f"![{title}]({figs[key]})"]
    t = doc["timing"]
    lines += ["", f"{t['simulations']} simulations, {t['wall_s']} s wall."]
    (out / "report.md").write_text("\n".join(lines) + "\n")
