"""Draw docs/designs/<design>.png for every design of mast.core.designs, from the model's own code.

Run from the repository root:  python docs/designs/make_figures.py
Each figure: left, a 3-D view at a tilted pose (body frames from the design's description,
fmus/mechanism/designs.py); right, the plane of leg 1 at the home pose (sliders at 0.15 m)
with the symbols of the geometry parameter set.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fmus.mechanism.designs import describe, kinematic_engine  # noqa: E402
from mast.core.designs import DESIGNS  # noqa: E402
from mast.core.ssp import read_ssd  # noqa: E402

HERE = Path(__file__).parent
RHO_HOME = 0.15


def frames(desc, q):
    ev = desc.evaluate(list(q))
    legs = []
    for origin, R in ev.frames[:3]:
        B = np.array(origin, dtype=float)
        x_leg = np.array([R[0][0], R[1][0], R[2][0]], dtype=float)
        legs.append((B, B + desc.L * x_leg))
    P = np.array(ev.frames[3][0], dtype=float)
    Rp = np.array(ev.frames[3][1], dtype=float)
    return legs, P, Rp


def draw(design) -> Path:
    params = read_ssd(design.ssd).components["mechanism"].parameters
    desc = describe(params, design.name)
    eng = kinematic_engine(params)
    attached = bool(params["attached"])
    beta = desc.beta
    z0 = eng.dk((RHO_HOME,) * 3)[0][0]
    q = (z0 - 0.01, math.radians(8.0), math.radians(-10.0))
    fig = plt.figure(figsize=(13, 6))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    legs, P, R = frames(desc, q)
    style = dict(color="C0", lw=2.5) if attached else dict(color="0.6", lw=1.2, ls="--")
    for i, a in enumerate(desc.alpha):
        e = np.array([math.cos(a), math.sin(a), 0.0])
        d = math.cos(beta) * np.array([0, 0, 1.0]) - math.sin(beta) * e
        foot = desc.H * e
        ax.plot(*np.c_[foot, foot + 0.5 * d], color="0.5", lw=4)  # guide
        B, S = legs[i]
        ax.plot(*np.c_[B, S], **style)  # leg
        ax.scatter(*B, color="C3", s=45)  # carriage
        ax.text(
            *(foot + 0.52 * d), f"guide {i + 1}\n$\\alpha_{i + 1}$ = {math.degrees(a):.0f}°", ha="center", fontsize=8
        )
        ax.text(*(B + [0.015, 0, -0.03]), f"$\\rho_{i + 1}$", color="C3", fontsize=9)
    ring = np.array(
        [P + R @ (desc.r * np.array([math.cos(s), math.sin(s), 0.0])) for s in np.linspace(0, 2 * math.pi, 73)]
    )
    ax.plot(ring[:, 0], ring[:, 1], ring[:, 2], color="C1" if attached else "0.6", lw=1.5, ls="-" if attached else "--")
    for k, col in enumerate(("r", "g", "b")):
        ax.quiver(*P, *(0.12 * R[:, k]), color=col)
    ax.scatter(*P, color="k", s=15)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_box_aspect((1, 1, 0.7))
    note = "" if attached else "\nno mechanism attached: the dashed 3PRS only maps rho to the reported pose"
    ax.set_title(f"{design.title}\nz = {q[0]:.3f} m, ψ = 8°, θ = -10°{note}", fontsize=10)

    # the plane of leg 1 at home
    ax2 = fig.add_subplot(1, 2, 2)
    legs, P, R = frames(desc, (z0, 0.0, 0.0))
    e = np.array([math.cos(desc.alpha[0]), math.sin(desc.alpha[0]), 0.0])
    B, S = legs[0]
    radial = lambda v: float(v @ e)  # noqa: E731
    top = 0.5
    ax2.plot(
        [desc.H, desc.H - top * math.sin(beta)],
        [0, top * math.cos(beta)],
        color="0.5",
        lw=5,
        label=f"guide 1 (β = {math.degrees(beta):.0f}° from the vertical)",
    )
    ax2.plot([0, 0], [0, 0.55], color="k", lw=0.8, ls="-.")
    ax2.plot([radial(B), radial(S)], [B[2], S[2]], label="leg 1 (length L)", **style)
    ax2.plot(
        [-0.05, radial(S)],
        [S[2], S[2]],
        label="platform (radius r)",
        **(dict(color="C1", lw=3) if attached else dict(color="0.6", lw=1.2, ls="--")),
    )
    ax2.scatter([radial(B)], [B[2]], color="C3", zorder=5, label="carriage 1: revolute joint, axis t_1")
    ax2.scatter([radial(S)], [S[2]], color="C2", zorder=5, label="spherical joint S_1")
    ax2.scatter([0], [P[2]], color="k", zorder=5)
    ax2.annotate("P", (0, P[2]), xytext=(0.006, P[2] + 0.012))
    ax2.annotate("", (desc.H, -0.03), (0, -0.03), arrowprops=dict(arrowstyle="<->"))
    ax2.text(desc.H / 2, -0.05, "H (at z = 0)", ha="center")
    ax2.annotate("", (desc.r, S[2] + 0.04), (0, S[2] + 0.04), arrowprops=dict(arrowstyle="<->"))
    ax2.text(desc.r / 2, S[2] + 0.048, "r", ha="center")
    d = np.array([-math.sin(beta), math.cos(beta)])
    off = 0.025 * np.array([math.cos(beta), math.sin(beta)])
    foot = np.array([desc.H, 0.0]) + off
    ax2.annotate("", tuple(foot + RHO_HOME * d), tuple(foot), arrowprops=dict(arrowstyle="<->", color="C3"))
    ax2.text(
        *(foot + 0.5 * RHO_HOME * d + [0.008, 0]), f"ρ_1 = {RHO_HOME} m\n(along the guide)", color="C3", fontsize=8
    )
    ax2.text(0.01, 0.55, "centre axis", fontsize=8)
    ax2.set_aspect("equal")
    ax2.set_xlim(-0.08, max(desc.H, radial(B)) + 0.14)
    ax2.set_ylim(-0.08, 0.6)
    ax2.set_xlabel("radial distance along e_1 [m]")
    ax2.set_ylabel("height z [m]")
    ax2.grid(True, lw=0.3)
    ax2.legend(loc="lower left", bbox_to_anchor=(0.0, 0.1), fontsize=8)
    ax2.set_title(
        f"plane of leg 1 at home: sliders at {RHO_HOME} m, z = {z0:.4f} m\n"
        f"H = {desc.H} m, r = {desc.r} m, L = {desc.L} m",
        fontsize=10,
    )
    fig.tight_layout()
    out = HERE / f"{design.name}.png"
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out


def main() -> None:
    for design in DESIGNS:
        print(f"wrote {draw(design)}")


if __name__ == "__main__":
    main()
