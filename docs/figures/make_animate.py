"""Draw docs/figures/animate.png: `mast animate`'s page in headless Chromium (docs/animate.md).

Run from the repository root after `make build` (needs Chromium):  python docs/figures/make_animate.py
A theta sine of 5 deg at 2 Hz on the default system (the model objects on the FMUs' schedule), 1 s,
replayed; the picture is the page at t = 0.6 s, where the platform lags the commanded pose (the ghost).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from mast.analyses import animate
from mast.core.build import default_build_dir
from mast.core.run import motion_from_cli, simulate, write_outputs

SSP = default_build_dir() / "ssp" / "MAST.ssp"
OUT = Path(__file__).with_name("animate.png")


def main() -> None:
    motion = motion_from_cli("theta", 5.0, 2.0)
    with tempfile.TemporaryDirectory(prefix="mast_animate_figure_") as tmp:
        run_dir = Path(tmp) / "theta_2Hz"
        write_outputs(simulate(SSP, motion, 1.0, direct=True), run_dir, 1.0, motion, SSP)
        page = animate.write(run_dir, Path(tmp) / "page.html")["out"]
        animate.screenshot(page, OUT, at=0.6, size=(900, 720))
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
