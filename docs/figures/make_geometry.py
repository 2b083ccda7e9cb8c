"""Draw docs/figures/geometry.png: the 3PRS geometry of fmus.mechanism.kinematics.

Run from the repository root:  python docs/figures/make_geometry.py
Left: 3-D view of the T layout at a tilted pose. Right: the vertical radial plane of
leg 1 with the symbols H, r, L, rho_1, gamma_1, d_1 and the platform centre P.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fmus.mechanism.kinematics import Geometry, full_pose  # noqa: E402

OUT = Path(__file__).with_name("geometry.png")


def main() -> None:
    geom = Geometry(0.4, 0.35, 0.26, (0.0, math.pi / 2, math.pi))
    pose = full_pose(geom, 0.40, math.radians(8.0), math.radians(-10.0))
    fig = plt.figure(figsize=(13, 6))

    # ---- 3-D view
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    P = np.array([pose.x, pose.y, pose.z])
    for i in range(3):
        a = geom.alpha[i]
        e = np.array([math.cos(a), math.sin(a), 0.0])
        base = geom.H * e
        ax.plot(*np.c_[base, base + [0, 0, 0.5]], color="0.6", lw=3)  # guide
        B, S = pose.sliders[i], pose.S[i]
        ax.plot(*np.c_[B, S], color="C0", lw=2.5)  # leg
        ax.scatter(*B, color="C3", s=40)
        ax.scatter(*S, color="C2", s=40)
        ax.text(
            *(base + [0, 0, 0.52]),
            f"guide {i + 1}\n$\\alpha_{i + 1}$ = {math.degrees(a):.0f}°",
            ha="center",
            fontsize=8,
        )
        ax.text(*(B + [0.01, 0, -0.03]), f"$\\rho_{i + 1}$", fontsize=9, color="C3")
    ring = np.array(
        [P + pose.R @ (geom.r * np.array([math.cos(s), math.sin(s), 0.0])) for s in np.linspace(0, 2 * math.pi, 73)]
    )
    ax.plot(ring[:, 0], ring[:, 1], ring[:, 2], color="C1", lw=1.5)
    tri = np.vstack([pose.S, pose.S[:1]])
    ax.plot(tri[:, 0], tri[:, 1], tri[:, 2], color="C1", lw=1, ls="--")
    for k, (col, lab) in enumerate(zip(("r", "g", "b"), ("x'", "y'", "z'"))):
        ax.quiver(*P, *(0.12 * pose.R[:, k]), color=col)
        ax.text(*(P + 0.14 * pose.R[:, k]), lab, color=col)
    ax.scatter(*P, color="k", s=20)
    ax.text(*(P + [0.01, 0.01, 0.02]), "P (TCP, COM)")
    for k, (col, lab) in enumerate(zip(("r", "g", "b"), ("x", "y", "z"))):
        ax.quiver(0, 0, 0, *(0.15 * np.eye(3)[k]), color=col)
        ax.text(*(0.17 * np.eye(3)[k]), lab, color=col)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_box_aspect((1, 1, 0.7))
    ax.set_title("T layout, z = 0.40 m, ψ = 8°, θ = -10°\n(x, y, φ parasitic)", fontsize=10)

    # ---- radial plane of leg 1 at home
    ax2 = fig.add_subplot(1, 2, 2)
    home = full_pose(geom, 0.405147, 0.0, 0.0)
    H, r = geom.H, geom.r
    B, S = home.sliders[0], home.S[0]
    ax2.plot([H, H], [0, 0.5], color="0.6", lw=4, label="guide 1 (vertical)")
    ax2.plot([0, 0], [0, 0.5], color="k", lw=0.8, ls="-.")
    ax2.plot([B[0], S[0]], [B[2], S[2]], color="C0", lw=3, label="leg 1 (length L)")
    ax2.plot([-0.05, S[0]], [S[2], S[2]], color="C1", lw=3, label="platform (radius r)")
    ax2.scatter([B[0]], [B[2]], color="C3", zorder=5, label="revolute joint on slider 1 (axis t_1)")
    ax2.scatter([S[0]], [S[2]], color="C2", zorder=5, label="spherical joint S_1")
    ax2.scatter([0], [S[2]], color="k", zorder=5)
    ax2.annotate("P", (0, S[2]), xytext=(0.005, S[2] + 0.012))
    ax2.annotate("", (H, -0.03), (0, -0.03), arrowprops=dict(arrowstyle="<->"))
    ax2.text(H / 2, -0.045, "H", ha="center")
    ax2.annotate("", (r, S[2] + 0.04), (0, S[2] + 0.04), arrowprops=dict(arrowstyle="<->"))
    ax2.text(r / 2, S[2] + 0.048, "r (= d_1 at home)", ha="center")
    ax2.annotate("", (H + 0.02, B[2]), (H + 0.02, 0), arrowprops=dict(arrowstyle="<->", color="C3"))
    ax2.text(H + 0.025, B[2] / 2, "ρ_1", color="C3")
    ax2.annotate("", (S[0], B[2] - 0.02), (H, B[2] - 0.02), arrowprops=dict(arrowstyle="<->"))
    ax2.text((S[0] + H) / 2, B[2] - 0.04, "H - d_1 = L cos γ_1", ha="center", fontsize=8)
    arc = np.linspace(math.pi - home.gamma[0], math.pi, 30)
    ax2.plot(B[0] + 0.05 * np.cos(arc), B[2] + 0.05 * np.sin(arc), color="C0")
    ax2.text(B[0] - 0.075, B[2] + 0.015, "γ_1", color="C0")
    ax2.plot([B[0] - 0.08, B[0]], [B[2], B[2]], color="C0", lw=0.6, ls=":")
    ax2.plot([0, H + 0.05], [0, 0], color="k", lw=1)
    ax2.text(0.002, 0.005, "base plane z = 0", fontsize=8)
    ax2.set_xlim(-0.08, 0.5)
    ax2.set_ylim(-0.07, 0.52)
    ax2.set_aspect("equal")
    ax2.set_xlabel("radial coordinate along e_1 [m]")
    ax2.set_ylabel("z [m]")
    ax2.set_title("Vertical radial plane of leg 1 at home (ρ = 0.15 m)", fontsize=10)
    ax2.legend(loc="lower left", bbox_to_anchor=(0.02, 0.15), fontsize=7)
    fig.tight_layout()
    fig.savefig(OUT, dpi=120)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
