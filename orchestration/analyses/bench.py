"""`mast bench`: real-time factor of the default system, FMU co-simulation vs direct composition.

Side by side in one run: the direct composition, the Python FMUs and, when ``mast build --native``
made it, the same system with the native FMUs (``build/ssp/native/<name>.ssp``), all on this
project's master. Wall and CPU time of this process. Prints figures; asserts nothing (speed is
measured here, not in tests).
"""

from __future__ import annotations

import cProfile
import io
import pstats
import resource
import time
from pathlib import Path
from typing import Optional

from ..core.motion import SineMotion
from ..core.run import simulate


def _one(ssp: str, stop_time: float, direct: bool) -> tuple[float, float]:
    """(wall, CPU) seconds of one run (the CPU time of this process: the FMUs run in it)."""
    cpu = time.process_time()
    result = simulate(ssp, SineMotion("z", 0.01, 1.0), stop_time, direct=direct)
    return result.wall_time_s, time.process_time() - cpu


def native_variant(ssp: str) -> Optional[Path]:
    """The native form of a built SSP (``build/ssp/X.ssp`` -> ``build/ssp/native/X.ssp``), if it was built."""
    path = Path(ssp)
    candidate = path.parent / "native" / path.name
    return candidate if path.parent.name != "native" and candidate.exists() else None


def main(args) -> int:
    stop = args.stop_time
    from ..core.exchange import library

    print(
        f"default system, {stop:g} s simulated, z sine 10 mm at 1 Hz, default cycle times, one process; "
        f"the master's exchange loop between FMUs {'compiled' if library() else 'in Python'} "
        "(MAST_PYTHON_EXCHANGE=1: in Python)"
    )
    rows = [("direct composition", args.ssp, True), ("Python FMUs", args.ssp, False)]
    native = native_variant(args.ssp)
    if native is not None:
        rows.append(("native FMUs", str(native), False))
    times = {}
    for label, ssp, direct in rows:
        wall, cpu = times[label] = _one(ssp, stop, direct)
        print(f"{label:19s}: {wall:7.2f} s wall {cpu:7.2f} s CPU  real-time factor (CPU) {stop / cpu:7.2f}")
    base = times["direct composition"][1]
    print(f"co-simulation / direct CPU-time ratio: Python FMUs {times['Python FMUs'][1] / base:.2f}", end="")
    if native is not None:
        print(
            f", native FMUs {times['native FMUs'][1] / base:.2f}; Python / native FMUs "
            f"{times['Python FMUs'][1] / times['native FMUs'][1]:.1f}"
        )
    else:
        print(f"\n(no native variant {Path(args.ssp).parent / 'native' / Path(args.ssp).name}: mast build --native)")
    print(f"peak resident memory: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")
    if args.profile:
        for direct_run in (True, False):
            prof = cProfile.Profile()
            prof.enable()
            _one(args.ssp, min(stop, 2.0), direct_run)
            prof.disable()
            text = io.StringIO()
            pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(15)
            print(("direct" if direct_run else "co-simulation") + " profile (2 s simulated), by own time:")
            print("\n".join(text.getvalue().splitlines()[:40]))
    return 0
