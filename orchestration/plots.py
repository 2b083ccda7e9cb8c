"""Figures of a run: commanded vs achieved motion, joint tracking, motor torques."""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from .master import Result  # noqa: E402


def plot_run(result: Result, axis: str, path: Path) -> None:
    t = result.time
    scale, unit = (1e3, "mm") if axis == "z" else (180 / math.pi, "deg")
    fig, axes = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    ax = axes[0]
    if f"{axis}_cmd" in result.signals:
        ax.plot(t, result[f"{axis}_cmd"] * scale, "k--", label=f"{axis} commanded")
    if f"mechanism.{axis}" in result.signals:
        ax.plot(t, result[f"mechanism.{axis}"] * scale, label=f"{axis} achieved")
    ax.set_ylabel(f"{axis} [{unit}]")
    ax.legend(loc="upper right")
    ax.set_title("Platform pose: commanded vs achieved")
    ax = axes[1]
    for j in (1, 2, 3):
        if f"controller.rho_cmd_{j}" in result.signals and f"actuator_{j}.rho" in result.signals:
            line, = ax.plot(t, result[f"actuator_{j}.rho"] * 1e3, label=f"rho_{j}")
            ax.plot(t, result[f"controller.rho_cmd_{j}"] * 1e3, "--", color=line.get_color(), label=f"rho_cmd_{j}")
    ax.set_ylabel("guide position [mm]")
    ax.legend(loc="upper right", ncol=3, fontsize="small")
    ax = axes[2]
    for j in (1, 2, 3):
        if f"actuator_{j}.tau_m" in result.signals:
            ax.plot(t, result[f"actuator_{j}.tau_m"], label=f"tau_m_{j}")
    ax.set_ylabel("motor torque [N m]")
    ax.set_xlabel("time [s]")
    ax.legend(loc="upper right", ncol=3, fontsize="small")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
