"""Benchmark: CPU time per step of the actuator model with a fixed and with a varying communication step.

    python benchmarks/variable_step.py [--steps 4000] [--repeats 3]

The actuator discretises its linear part exactly for each step size (zero-order hold). Hosts with
variable steps exist; this prints, side by side, the CPU time per step with a fixed step of 100 us,
with a step that varies at every call (uniform in 50-150 us, seeded), and with a step that
alternates between two values, for the default parameter sets and for the identified set
(Coulomb friction), and the ratios varying / fixed. Two figures per pattern: over all steps of a
fresh block (with its one-time work: a kernel compiled for each of the first step sizes, the
reference exponentials of a varying step), and in steady state (the second half of the steps).
The other blocks do not depend on the step size this way (the controller accepts whole multiples of
its cycle only, the mechanism is algebraic). Every figure is the minimum over ``--repeats``
interleaved repeats (the machine may be shared).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from fmus.actuator.model import ActuatorBlock  # noqa: E402
from mast.core.ssp import read_ssd  # noqa: E402
from mast.core.ssv import read_values  # noqa: E402


def parameter_sets() -> dict[str, dict]:
    """The default system's actuator_1 bindings and the identified set over them, restricted to the voltage-driven
    ActuatorBlock's parameters (actuator_1 is the drive: drive.ssv also binds the current loop's, e.g. T_cur)."""
    base = dict(read_ssd(REPO / "ssp" / "MAST.ssd").components["actuator_1"].parameters)
    identified = {**base, **read_values(REPO / "ssp" / "resources" / "actuator_identified.ssv")}
    names = {p.name for p in ActuatorBlock.PARAMETERS}
    return {
        label: {k: v for k, v in values.items() if k in names}
        for label, values in (("manufacturer", base), ("identified (friction)", identified))
    }


def per_step(params: dict, steps: np.ndarray) -> tuple[float, float]:
    """CPU seconds per do_step over ``steps`` and over their second half (a fresh block, a 2 Hz voltage,
    a constant load)."""
    block = ActuatorBlock(params, name="bench")
    block.values[0], block.values[1] = 0.0, 6.0
    block.initialize(0.0)
    t = 0.0
    u = 4.0 * np.sin(2 * np.pi * 2.0 * np.cumsum(steps))
    half = len(steps) // 2
    start = time.process_time()
    for k, (h, volts) in enumerate(zip(steps.tolist(), u.tolist())):
        if k == half:
            middle = time.process_time()
        block.values[0] = volts
        block.do_step(t, h)
        t += h
    end = time.process_time()
    return (end - start) / len(steps), (end - middle) / (len(steps) - half)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=4000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(1)
    patterns = {
        "fixed 100 us": np.full(args.steps, 1e-4),
        "varying 50-150 us": rng.uniform(0.5e-4, 1.5e-4, args.steps),
        "alternating 90/110 us": np.tile([0.9e-4, 1.1e-4], args.steps // 2),
    }
    print(f"actuator do_step, CPU time per step (minimum of {args.repeats} repeats of {args.steps} steps)")
    print(f"{'parameter set':<24}{'':<14}" + "".join(f"{name:>24}" for name in patterns) + f"{'varying / fixed':>18}")
    for label, params in parameter_sets().items():
        best = {name: [float("inf"), float("inf")] for name in patterns}
        for _ in range(args.repeats):
            for name, steps in patterns.items():
                best[name] = [min(b, f) for b, f in zip(best[name], per_step(params, steps))]
        for column, what in enumerate(("all steps", "steady state")):
            ratio = best["varying 50-150 us"][column] / best["fixed 100 us"][column]
            print(
                f"{label if column == 0 else '':<24}{what:<14}"
                + "".join(f"{best[n][column] * 1e6:>21.1f} us" for n in patterns)
                + f"{ratio:>17.1f}x"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
