"""`mast bench`: real-time factor of the default system, FMU co-simulation vs direct composition.

Prints figures; asserts nothing (speed is measured here, not in tests).
"""
from __future__ import annotations

import cProfile
import io
import pstats
import resource

from .run import simulate
from .motion import SineMotion


def _one(ssp: str, stop_time: float, direct: bool) -> float:
    result = simulate(ssp, SineMotion("z", 0.01, 1.0), stop_time, direct=direct)
    return result.wall_time_s


def main(args) -> int:
    stop = args.stop_time
    print(f"default system, {stop:g} s simulated, z sine 10 mm at 1 Hz, default cycle times, one process")
    direct = _one(args.ssp, stop, True)
    print(f"direct composition : {direct:7.2f} s wall  real-time factor {stop / direct:6.2f}")
    cosim = _one(args.ssp, stop, False)
    print(f"FMU co-simulation  : {cosim:7.2f} s wall  real-time factor {stop / cosim:6.2f}")
    print(f"co-simulation / direct wall-time ratio: {cosim / direct:.2f}")
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
