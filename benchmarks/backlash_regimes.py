"""Regimes of the hunting that backlash causes: how often re-simulations visit the regime a record is in.

The measurement behind docs/diagnose.md, "Backlash on the issue's plan: why one record is not reproduced".
One z sine test (default: the issue plan's z 3.5 Hz, 3 mm, 0.8 s, analysed from 0.2 s) with backlash is
synthesized the way ``mast synthesize`` makes a record (Python models, direct composition, the exact sine);
its torque residual against the nominal model (no backlash, the logged commands replayed) gives the
phase-free score's band powers (orchestration/diagnosis/phasefree.py). Then:
  - the synthesis's own path again (must reproduce the record bit for bit),
  - the logged commands replayed on the Python models, as the diagnosis does, with and without the
    command perturbation of its ensembles (phasefree.COMMAND_JITTER),
  - N runs of the exact sine with its amplitude perturbed by 1e-13 to 1e-9 (relative) on the native
    models (``mast build --native``): the distribution of the band powers, and how many runs are as quiet
    as the record below 20 Hz (within 3 x of its power).
Usage:
    .venv/bin/python benchmarks/backlash_regimes.py [--backlash 0.004] [--runs 60] [--duration 0.8]
Costs about 0.15 s of CPU per native run and a few seconds per Python run (0.8 s tests).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from fmus.actuator.sensor import measure
from mast.analyses.synthesize import DEFAULT_TORQUE_FILTER, TestSpec, synthesize
from mast.core.build import default_build_dir
from mast.core.motion import SineMotion
from mast.core.run import drive_tick_steps, simulate
from mast.core.ssp import SSPArchive
from mast.data.measured import AXES, CommandReplay, controller_kinematics, load
from mast.diagnosis.phasefree import COMMAND_JITTER, BandPowers


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ssp", default=str(default_build_dir() / "ssp" / "MAST.ssp"))
    ap.add_argument("--backlash", type=float, default=0.004, help="rad (default 4 mrad)")
    ap.add_argument("--amplitude", type=float, default=0.003, help="m")
    ap.add_argument("--frequency", type=float, default=3.5, help="Hz")
    ap.add_argument("--duration", type=float, default=0.8, help="s")
    ap.add_argument("--settle", type=float, default=0.2, help="s: the analysis starts here")
    ap.add_argument("--runs", type=int, default=60, help="perturbed native runs")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    native = Path(args.ssp).parent / "native" / Path(args.ssp).name
    if not native.exists():
        raise SystemExit(f"{native}: no native variant: run `mast build --native` first")
    with SSPArchive(args.ssp) as archive:
        steps = drive_tick_steps(archive.system)
    spec = TestSpec("z", args.amplitude, args.frequency, args.duration, args.settle)
    truth = {f"actuator_{j}": {"backlash": args.backlash} for j in AXES}
    record = [f"actuator_{j}.tau_meas" for j in AXES]

    def observed(stimulus, ssp: str, params: dict, direct: bool) -> np.ndarray:
        """The torque as the synthesis logs it (drive filter, sampled at 1 ms), without the noise."""
        res = simulate(
            ssp,
            stimulus,
            spec.stop_time(),
            parameters=params,
            record=record,
            record_step=None,
            direct=direct,
            base_step=steps and steps[0],
            step_sizes=steps and steps[1],
        )
        tau = np.column_stack([res[f"actuator_{j}.tau_meas"] for j in AXES])
        every = round(1e-3 / res.stats["base_step"])
        return measure(tau, res.stats["base_step"], T=DEFAULT_TORQUE_FILTER, axis=0)[::every]

    with tempfile.TemporaryDirectory(prefix="mast_regimes_") as tmp:
        out = synthesize(args.ssp, Path(tmp) / "data", truth, tests=[spec], direct=True, seed=0, log=lambda *_: None)
        test = load(Path(tmp) / "data").tests[0]
    clean = out["clean"][spec.name]["tau_m"]
    replay = CommandReplay(test.time, test.rho_cmd, controller_kinematics(args.ssp))
    reference = observed(replay, str(native), {}, False)
    keep = test.time >= test.settle_s - 1e-12
    bands = BandPowers(1e-3)

    def powers(y: np.ndarray) -> np.ndarray:
        n = min(len(y), len(reference))
        return bands.powers((y[:n] - reference[:n])[keep[:n]])

    def show(label: str, p: np.ndarray) -> None:
        print(f"{label:58s} " + "  ".join(f"{v:9.3g}" for v in p))

    print(
        f"{spec.name}, {args.amplitude * 1e3:g} mm, {args.duration:g} s (from {args.settle:g} s), backlash "
        f"{args.backlash * 1e3:g} mrad; band powers of the torque residual [N^2 m^2], bands "
        + ", ".join(f"{lo:g}-{hi:g}" for lo, hi in bands.bands)
        + " Hz"
    )
    rec = powers(clean)
    show("the record (synthesis, exact sine, no noise)", rec)
    again = observed(SineMotion("z", args.amplitude, args.frequency), args.ssp, truth, True)
    print(f"{'the synthesis path again: max |difference| [N m]':58s} {np.abs(again - clean).max():.3g}")
    for r in range(3):
        rp = replay.perturbed(r, COMMAND_JITTER) if r else replay
        show(f"logged commands replayed, Python models, realisation {r}", powers(observed(rp, args.ssp, truth, True)))
    rng = np.random.default_rng(args.seed)
    rows = []
    t0 = time.process_time()
    for k in range(args.runs):
        eps = 10 ** rng.uniform(-13, -9) * rng.choice([-1.0, 1.0])
        rows.append(
            powers(observed(SineMotion("z", args.amplitude * (1 + eps), args.frequency), str(native), truth, False))
        )
        if (k + 1) % 10 == 0:
            print(f"  {k + 1}/{args.runs} native runs", flush=True)
    rows = np.array(rows)
    for q in (0, 5, 50, 95, 100):
        show(f"native runs, amplitude perturbed: {q}th percentile", np.percentile(rows, q, axis=0))
    quiet = int(np.sum(rows[:, 0] <= 3.0 * rec[0]))
    print(
        f"runs as quiet as the record below {bands.bands[0][1]:g} Hz (<= 3 x its power): {quiet} of {len(rows)}; "
        f"runs below the record in every band: {int(np.sum(np.all(rows <= rec, axis=1)))}; "
        f"CPU {time.process_time() - t0:.1f} s for the native runs"
    )


if __name__ == "__main__":
    main()
