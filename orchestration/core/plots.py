"""Figures of a run: commanded vs achieved motion of every coordinate, joint tracking, motor torques."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from fmus.mechanism.topology import POSE  # noqa: E402

from .master import Result  # noqa: E402
from .motion import unit as axis_unit  # noqa: E402


def plot_run(result: Result, axis: str, path: Path) -> None:
    """motion.png: the moved ``axis`` commanded and achieved; every other coordinate's departure from its start
    (translations in mm, rotations in deg: the ones held); every drive's position and command; every motor's torque."""
    t = result.time
    scale, unit = (1e3, "mm") if axis_unit(axis) == "m" else (180 / math.pi, "deg")
    ks = result.drives()
    ncol = 3 if len(ks) <= 3 else 4
    fig, axes = plt.subplots(4, 1, figsize=(9, 11), sharex=True)
    ax = axes[0]
    if f"{axis}_cmd" in result.signals:
        ax.plot(t, result[f"{axis}_cmd"] * scale, "k--", label=f"{axis} commanded")
    if f"mechanism.{axis}" in result.signals:
        ax.plot(t, result[f"mechanism.{axis}"] * scale, label=f"{axis} achieved")
    ax.set_ylabel(f"{axis} [{unit}]")
    _legend(ax)
    ax.set_title("Platform pose: commanded vs achieved")
    ax = axes[1]
    held = [c for c in result.coordinates() if c != axis and f"mechanism.{c}" in result.signals]
    rotations = ax.twinx() if any(axis_unit(c) == "rad" for c in held) else None
    for c in held:
        rad = axis_unit(c) == "rad"
        target = rotations if rad else ax
        departure = (result[f"mechanism.{c}"] - result[f"{c}_cmd"]) * (180 / math.pi if rad else 1e3)
        style = dict(linestyle=":" if rad else "-", color=f"C{POSE.index(c)}")
        target.plot(t, departure, label=f"{c} [{'deg' if rad else 'mm'}]", **style)
    ax.set_ylabel("held coordinates, achieved - commanded [mm]")
    if rotations is not None:
        rotations.set_ylabel("[deg]")
        lines = ax.get_legend_handles_labels()
        more = rotations.get_legend_handles_labels()
        if lines[0] or more[0]:
            ax.legend(lines[0] + more[0], lines[1] + more[1], loc="upper right", ncol=ncol, fontsize="small")
    else:
        _legend(ax, ncol=ncol)
    ax = axes[2]
    for j in ks:
        if f"controller.rho_cmd_{j}" in result.signals and f"actuator_{j}.rho" in result.signals:
            (line,) = ax.plot(t, result[f"actuator_{j}.rho"] * 1e3, label=f"rho_{j}")
            ax.plot(t, result[f"controller.rho_cmd_{j}"] * 1e3, "--", color=line.get_color(), label=f"rho_cmd_{j}")
    ax.set_ylabel("guide position [mm]")
    _legend(ax, ncol=ncol)
    ax = axes[3]
    for j in ks:
        if f"actuator_{j}.tau_m" in result.signals:
            ax.plot(t, result[f"actuator_{j}.tau_m"], label=f"tau_m_{j}")
    ax.set_ylabel("motor torque [N m]")
    ax.set_xlabel("time [s]")
    _legend(ax, ncol=ncol)
    for ax in axes:
        ax.grid(True, alpha=0.3)
        if not ax.get_legend_handles_labels()[0] and not ax.get_legend():
            ax.text(0.5, 0.5, "not recorded", transform=ax.transAxes, ha="center", color="gray")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _legend(ax, ncol: int = 1) -> None:
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right", ncol=ncol, fontsize="small")
