"""Per-step cost of the mechanism's hot path: direct kinematics (warm start) and MechanismBlock.do_step.

Runs the default design's mechanism block along a 1 Hz sine of every axis (1 ms steps, the
co-simulation's schedule) and prints the CPU time per call. Usage:
    .venv/bin/python benchmarks/dk_step.py [--steps N] [--repeat R]
Run it before and after a change of engine.dk or MechanismBlock (timings are noisy on a shared
machine: the best of R repeats is printed).
"""

from __future__ import annotations

import argparse
import math
import time

from fmus.mechanism.model import MechanismBlock
from mast.core.designs import DESIGNS
from mast.core.ssp import read_ssd


def trajectory(eng, steps: int) -> list[tuple]:
    """Joint motions (rho, rho_dot, rho_ddot) of a 1 Hz sine in z, psi, theta around home, 1 ms apart."""
    home = eng.dk((0.15, 0.15, 0.15))[0]
    amp = (0.01, math.radians(2.0), math.radians(2.0))
    out, h = [], 1e-3
    for k in range(steps):
        t = k * h
        q = [home[j] + amp[j] * math.sin(2 * math.pi * t) for j in range(3)]
        qn = [home[j] + amp[j] * math.sin(2 * math.pi * (t + h)) for j in range(3)]
        rho, rhon = eng.ik(q), eng.ik(qn)
        out.append((*rho, *((b - a) / h for a, b in zip(rho, rhon)), 0.0, 0.0, 0.0))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    for d in DESIGNS[:3]:
        params = dict(read_ssd(d.ssd).components["mechanism"].parameters)
        blk = MechanismBlock(params, "mechanism")
        eng = blk.engine
        inputs = trajectory(eng, args.steps)
        best_dk = best_step = math.inf
        for _ in range(args.repeat):
            guess = eng.dk(inputs[0][:3])[0]
            t0 = time.process_time()
            for u in inputs:
                guess = eng.dk(u[:3], guess)[0]
            best_dk = min(best_dk, (time.process_time() - t0) / len(inputs))
            blk.values[0:9] = inputs[0]
            blk.initialize(0.0)
            t0 = time.process_time()
            for k, u in enumerate(inputs):
                blk.values[0:9] = u
                blk.do_step(k * 1e-3, 1e-3)
            best_step = min(best_step, (time.process_time() - t0) / len(inputs))
        print(
            f"{d.name:14s} dk (warm) {best_dk * 1e6:6.1f} us/call   MechanismBlock.do_step {best_step * 1e6:6.1f} "
            "us/step"
        )


if __name__ == "__main__":
    main()
