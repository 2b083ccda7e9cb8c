"""Size and writing time of `mast animate`'s page for 3 s of motion (issue 28's acceptance figures).

Runs the default system's `make run` motion (z sine, 0.01 m at 1 Hz, 3 s; the model objects on the FMUs'
schedule, the same numbers as through FMI) into a temporary run folder, or takes a run folder given, then
writes the page REPEAT times and prints the frames, the page's size (and how much of it is plotly.js) and
the best wall time. Usage:
    .venv/bin/python benchmarks/animate_page.py [RUN_DIR] [--ssp SSP] [--stop-time T] [--fps F] [--repeat R]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from mast.analyses import animate
from mast.core.build import default_build_dir
from mast.core.run import motion_from_cli, simulate, write_outputs

SSP = default_build_dir() / "ssp" / "MAST.ssp"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", nargs="?", help="a `mast run` folder (default: run the default system for 3 s)")
    parser.add_argument("--ssp", type=Path, default=SSP, help="the system run when no RUN_DIR is given")
    parser.add_argument("--stop-time", type=float, default=3.0, help="seconds of motion run when no RUN_DIR is given")
    parser.add_argument("--fps", type=float, default=animate.FPS)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="mast_animate_bench_") as tmp:
        run_dir = Path(args.run_dir) if args.run_dir else Path(tmp) / "z_1Hz"
        if not args.run_dir:
            motion = motion_from_cli("z", 0.01, 1.0)
            result = simulate(args.ssp, motion, args.stop_time, direct=True)
            write_outputs(result, run_dir, args.stop_time, motion, args.ssp)
        best = None
        for _ in range(args.repeat):
            start = time.perf_counter()
            done = animate.write(run_dir, Path(tmp) / "page.html", args.fps)
            wall = time.perf_counter() - start
            best = wall if best is None else min(best, wall)
        import plotly.offline

        library = len(plotly.offline.get_plotlyjs().encode("utf-8"))
        print(
            f"{done['frames']} frames ({args.fps:g} per simulated second, {done['simulated_s']:.3g} s of motion): "
            f"{done['bytes'] / 1e6:.2f} MB ({library / 1e6:.2f} MB of it plotly.js, "
            f"{(done['bytes'] - library) / 1e3:.0f} kB the figure), written in {best:.2f} s (best of {args.repeat})"
        )


if __name__ == "__main__":
    main()
