"""Figures of a run: commanded vs achieved motion, joint tracking, motor torques."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from .master import Result  # noqa: E402
from .motion import unit as axis_unit  # noqa: E402


def plot_run(result: Result, axis: str, path: Path) -> None:
    t = result.time
    scale, unit = (1e3, "mm") if axis_unit(axis) == "m" else (180 / math.pi, "deg")
    drives = range(
        1,
        1
        + max(
            (
                j
                for j in range(1, 100)
                if f"actuator_{j}.rho" in result.signals or f"actuator_{j}.tau_m" in result.signals
            ),
            default=0,
        ),
    )
    fig, axes = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    ax = axes[0]
    if f"{axis}_cmd" in result.signals:
        ax.plot(t, result[f"{axis}_cmd"] * scale, "k--", label=f"{axis} commanded")
    if f"mechanism.{axis}" in result.signals:
        ax.plot(t, result[f"mechanism.{axis}"] * scale, label=f"{axis} achieved")
    ax.set_ylabel(f"{axis} [{unit}]")
    _legend(ax)
    ax.set_title("Platform pose: commanded vs achieved")
    ax = axes[1]
    for j in drives:
        if f"controller.rho_cmd_{j}" in result.signals and f"actuator_{j}.rho" in result.signals:
            (line,) = ax.plot(t, result[f"actuator_{j}.rho"] * 1e3, label=f"rho_{j}")
            ax.plot(t, result[f"controller.rho_cmd_{j}"] * 1e3, "--", color=line.get_color(), label=f"rho_cmd_{j}")
    ax.set_ylabel("guide position [mm]")
    _legend(ax, ncol=3)
    ax = axes[2]
    for j in drives:
        if f"actuator_{j}.tau_m" in result.signals:
            ax.plot(t, result[f"actuator_{j}.tau_m"], label=f"tau_m_{j}")
    ax.set_ylabel("motor torque [N m]")
    ax.set_xlabel("time [s]")
    _legend(ax, ncol=3)
    for ax in axes:
        ax.grid(True, alpha=0.3)
        if not ax.get_legend_handles_labels()[0]:
            ax.text(0.5, 0.5, "not recorded", transform=ax.transAxes, ha="center", color="gray")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _legend(ax, ncol: int = 1) -> None:
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right", ncol=ncol, fontsize="small")
