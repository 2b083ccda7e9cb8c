"""Figures across a batch: metrics against the swept parameters, frequency responses, bandwidths."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Mapping, Optional, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fmus.mechanism.topology import POSE, POSE_UNITS  # noqa: E402

_MOTION_KEYS = {"frequency": "frequency", "amplitude": "amplitude", "axis": "axis"}


def plot_batch(
    folder: Path, records: Sequence[Mapping], groups: Sequence[Mapping], requested: Sequence[Mapping] = ()
) -> list[Path]:
    """The default plots, then the requested ``{x, y}`` ones; returns the written files."""
    folder.mkdir(parents=True, exist_ok=True)
    ok = [r for r in records if r.get("status") == "ok"]
    written = _defaults(folder, ok, groups)
    for spec in requested:
        path = _xy(folder, ok, groups, str(spec["x"]), str(spec["y"]))
        if path and path not in written:
            written.append(path)
    return written


def _defaults(folder: Path, ok: Sequence[Mapping], groups: Sequence[Mapping]) -> list[Path]:
    """Sweeps: their frequency responses, the bandwidth against every varied input, its histogram;
    otherwise a few headline metrics against every varied input."""
    written: list[Path] = []
    if groups:
        written.append(_frequency_responses(folder / "frequency_response.png", groups))
        for key in _varied(groups):
            path = _xy(folder, ok, groups, key, "bandwidth_Hz")
            if path:
                written.append(path)
        bws = np.array([_num(g.get("bandwidth_Hz")) for g in groups])
        if np.isfinite(bws).sum() >= 5:
            written.append(_histogram(folder / "bandwidth_histogram.png", bws[np.isfinite(bws)], "bandwidth [Hz]"))
        return written
    headline = _headline(ok)
    for key in _varied(ok)[:6]:
        for metric in headline:
            path = _xy(folder, ok, groups, key, metric)
            if path:
                written.append(path)
    return written


def _num(value) -> float:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else float("nan")


def _value(row: Mapping, key: str):
    if key in _MOTION_KEYS and row.get("motion"):
        return row["motion"].get(_MOTION_KEYS[key])
    if key == "sample":
        return row.get("sample")
    if key in row.get("inputs", {}):
        return row["inputs"][key]
    if key in row.get("parameters", {}):
        return row["parameters"][key]
    if key in (row.get("metrics") or {}):
        return row["metrics"][key]
    return row.get(key)


def _varied(rows: Sequence[Mapping]) -> list[str]:
    """Numeric inputs that take more than one value across ``rows``."""
    keys = list(dict.fromkeys(k for r in rows for k in r.get("inputs", {})))
    if any("inputs" not in r for r in rows):  # group rows carry the inputs at the top level
        keys = [k for k in dict.fromkeys(k for r in rows for k in r) if "." in k]
    out = []
    for key in keys:
        values = {_num(_value(r, key)) for r in rows}
        if len({v for v in values if math.isfinite(v)}) > 1:
            out.append(key)
    return out


def _headline(rows: Sequence[Mapping]) -> list[str]:
    """Up to three metrics to plot against the varied inputs: the response, the tracking of the coordinates the
    cases move (of every coordinate in pose order when none moves), the first drive's torque, saturation."""
    have = set(k for r in rows for k in (r.get("metrics") or {}))
    moved = list(dict.fromkeys(r["motion"]["axis"] for r in rows if r.get("motion")))
    tracking = [f"tracking_{a}_rms_{POSE_UNITS[a]}" for a in (moved or POSE)]
    picks = [m for m in ("magnitude_dB", *tracking, "tau_m_1_peak_Nm", "saturation_s") if m in have]
    return picks[:3]


def _xy(folder: Path, records: Sequence[Mapping], groups: Sequence[Mapping], x: str, y: str) -> Optional[Path]:
    group_metric = any(y in g for g in groups) and not any(y in (r.get("metrics") or {}) for r in records)
    rows = groups if group_metric else records
    getter = (lambda r, k: r.get(k)) if group_metric else _value
    xs = np.array([_num(getter(r, x)) for r in rows])
    ys = np.array([_num(getter(r, y)) for r in rows])
    good = np.isfinite(xs) & np.isfinite(ys)
    if not good.any():
        return None
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(xs[good], ys[good], "o", alpha=0.75)
    if good.sum() >= 3 and np.ptp(xs[good]) > 0:
        k, c = np.polyfit(xs[good], ys[good], 1)
        grid = np.linspace(xs[good].min(), xs[good].max(), 50)
        ax.plot(grid, k * grid + c, "k--", lw=1, label=f"linear fit: slope {k:.3g}")
        ax.legend(fontsize="small")
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    ax.set_title(f"{y} against {x} ({good.sum()} {'groups' if group_metric else 'cases'})")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    path = folder / f"{_slug(y)}_vs_{_slug(x)}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _frequency_responses(path: Path, groups: Sequence[Mapping]) -> Path:
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    fig, (ax_m, ax_p) = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    alpha = 0.9 if len(groups) <= 5 else max(0.15, 3.0 / len(groups))
    varied = _varying_keys(groups)
    freqs: set = set()
    for g in groups:
        f = np.array(g.get("frequencies_Hz", []), dtype=float)
        if not len(f):
            continue
        freqs.update(f.tolist())
        order = np.argsort(f)
        mag = 20 * np.log10(np.maximum(np.array(g["magnitudes"], dtype=float)[order], 1e-12))
        ax_m.semilogx(f[order], mag, "-o", ms=3, alpha=alpha, label=_label(g, varied) if len(groups) <= 5 else None)
        ax_p.semilogx(f[order], np.array(g["phases_deg"], dtype=float)[order], "-o", ms=3, alpha=alpha)
    ax_m.axhline(-3.0, color="k", ls=":", lw=1)
    ax_m.set_ylabel("magnitude [dB]")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel("frequency [Hz]")
    ax_m.set_title(f"closed-loop response, {len(groups)} sweep(s)")
    if len(groups) <= 5 and varied:
        ax_m.legend(fontsize="x-small", loc="lower left")
    if 0 < len(freqs) <= 12:
        ax_p.set_xticks(sorted(freqs))
    for ax in (ax_m, ax_p):
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _histogram(path: Path, values: np.ndarray, label: str) -> Path:
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.hist(values, bins=min(30, max(5, len(values) // 3)))
    ax.set_xlabel(label)
    ax.set_ylabel("groups")
    ax.set_title(
        f"{label}: mean {values.mean():.3g}, std {values.std(ddof=1) if len(values) > 1 else 0:.2g}, "
        f"min {values.min():.3g}, max {values.max():.3g}"
    )
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _varying_keys(groups: Sequence[Mapping]) -> list[str]:
    """What tells the groups apart: ssp, axis, amplitude and the inputs that differ between them."""
    keys = ["ssp", "axis", "amplitude"] + list(dict.fromkeys(k for g in groups for k in g if "." in k))
    return [k for k in keys if len({str(g.get(k)) for g in groups}) > 1]


def _label(group: Mapping, keys: Sequence[str]) -> str:
    parts = []
    for k in keys[:3]:
        v = group.get(k)
        parts.append(f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}")
    text = ", ".join(parts) + (", ..." if len(keys) > 3 else "")
    return text if len(text) <= 70 else text[:67] + "..."


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text.replace("*", "all")).strip("_")
