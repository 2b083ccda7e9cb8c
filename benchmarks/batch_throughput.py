"""Batch benchmark: throughput with 1 and 2 workers, per-case overhead, single-run real-time factor,
and where a run's time goes (physics vs FMU plumbing).

    python benchmarks/batch_throughput.py [--ssp build/ssp/MAST.ssp] [--cases 24] [--stop-time 1.0]
                                          [--repeats 3] [--json results/bench_batch.json] [--profile]

The machine may be shared: every figure is the minimum over interleaved repeats (the least disturbed).
Needs `mast build` first; the direct-route figures assume fmus/ is the code the FMUs were built from.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import math
import os
import pstats
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

from mast.core.build import default_build_dir

RECORD = (
    ["z_cmd", "mechanism.z", "psi_cmd", "mechanism.psi", "theta_cmd", "mechanism.theta"]
    + [f"actuator_{k}.{s}" for k in (1, 2, 3) for s in ("tau_m", "i_m", "u")]
    + [f"controller.i_cmd_{k}" for k in (1, 2, 3)]
)  # the voltage u is the actuator's (its drive's current loop)


class _PhysicsClock:
    """Times every model block's ``do_step`` (the physics), in the FMUs' bundled copies of the model
    code and in ``fmus`` itself, so a run splits into physics and everything else (the plumbing)."""

    def __init__(self) -> None:
        self.total = 0.0
        self.enabled = False
        self._patched: list = []

    def install(self) -> None:
        for name, module in list(sys.modules.items()):
            if not (name.startswith("fmus.") or name.startswith("mast_")) or module is None:
                continue
            for cls in list(vars(module).values()):
                if (
                    isinstance(cls, type)
                    and "do_step" in vars(cls)
                    and hasattr(cls, "INPUTS")
                    and cls.__module__ == name
                    and not any(cls is c for c, _ in self._patched)
                ):
                    self._wrap(cls)

    def _wrap(self, cls) -> None:
        original, clock, state = cls.do_step, time.perf_counter, self

        def do_step(block, t, h):
            if not state.enabled:
                return original(block, t, h)
            t0 = clock()
            try:
                return original(block, t, h)
            finally:
                state.total += clock() - t0

        cls.do_step = do_step
        self._patched.append((cls, original))

    def uninstall(self) -> None:
        for cls, original in self._patched:
            cls.do_step = original
        self._patched.clear()


def single_run(ssp: str, stop: float, repeats: int) -> dict:
    """Real-time factor of one run on a warm session, and its split into physics and plumbing
    (physics timed inside the same run: the split does not depend on how busy the machine is)."""
    from mast.core.components import FMUComponent
    from mast.core.motion import SineMotion
    from mast.core.run import simulate
    from mast.core.session import Session

    motion = lambda: SineMotion("z", 0.005, 5.0)  # noqa: E731
    best: dict[str, float] = {}
    split: dict[str, tuple[float, float]] = {}

    def keep(key: str, value: float) -> None:
        best[key] = min(best.get(key, math.inf), value)

    sessions = {"fmu": Session(ssp), "fmu_fmpy_calls": Session(ssp), "direct": Session(ssp, direct=True)}

    def _calls(key: str) -> None:
        """fmu: the master's compiled exchange loop; fmu_fmpy_calls: its Python loop through fmpy's prototypes."""
        FMUComponent.fast_calls = key != "fmu_fmpy_calls"
        os.environ["MAST_PYTHON_EXCHANGE"] = "1" if key == "fmu_fmpy_calls" else "0"

    physics = _PhysicsClock()
    try:
        for key, session in sessions.items():  # warm up: every model module loaded
            _calls(key)
            session.run(motion(), 0.05, record=RECORD)
        physics.install()
        for _rep in range(repeats):
            for key, session in sessions.items():
                _calls(key)
                result = session.run(motion(), stop, record=RECORD)
                keep(f"{key}_step_s", result.wall_time_s - result.stats["init_s"])
                keep(f"{key}_init_s", result.stats["init_s"])
                keep(f"{key}_setup_s", session.last_setup_s)
                physics.total, physics.enabled = 0.0, True
                result = session.run(motion(), stop, record=RECORD)
                physics.enabled = False
                step = result.wall_time_s - result.stats["init_s"]
                if key not in split or step < split[key][0]:
                    split[key] = (step, physics.total)
            t0 = time.perf_counter()
            result = simulate(ssp, motion(), stop, record=RECORD)
            keep("simulate_total_s", time.perf_counter() - t0)
            keep("simulate_step_s", result.wall_time_s - result.stats["init_s"])
    finally:
        _calls("fmu")
        physics.uninstall()
        for session in sessions.values():
            session.close()
    best["stop_time_s"] = stop
    best["rtf_fmu"] = stop / best["fmu_step_s"]
    best["rtf_direct"] = stop / best["direct_step_s"]
    for key, (step, phys) in split.items():
        best[f"{key}_timed_step_s"], best[f"{key}_physics_s"] = step, phys
        best[f"{key}_plumbing_s"] = step - phys
        best[f"{key}_plumbing_over_physics"] = (step - phys) / phys
    best["simulate_overhead_s"] = best["simulate_total_s"] - best["simulate_step_s"]
    return best


def batch_runs(ssp: str, cases: int, stop: float, repeats: int) -> dict:
    from mast.batch import run_batch

    masses = [1.8 + 0.02 * k for k in range(cases)]
    config = {
        "name": "bench",
        "ssp": ssp,
        "run": {"stop_time": stop, "record_step": 1e-3},
        "cases": {
            "motion": {"axis": "z", "amplitude": 0.005, "frequency": 5.0},
            "list": [{"mechanism.m_platform": m} for m in masses],
        },
    }
    out: dict = {"cases": cases, "stop_time_s": stop, "runs": []}
    tmp = Path(tempfile.mkdtemp(prefix="mast_bench_batch_"))
    try:
        for rep in range(repeats):
            for workers in (1, 2):
                folder = tmp / f"w{workers}_{rep}"
                result = run_batch(config, folder, workers=workers, progress=False, plots=False)
                ok = [r for r in result.records if r["status"] == "ok"]
                timing = [r["timing"] for r in ok]
                out["runs"].append(
                    {
                        "workers": workers,
                        "wall_s": result.wall_s,
                        "ok": len(ok),
                        "step_s": statistics.mean(t["step_s"] for t in timing),
                        "init_s": statistics.mean(t["init_s"] for t in timing),
                        "setup_s": statistics.median(t["setup_s"] for t in timing),
                        "first_setup_s": max(t["setup_s"] for t in timing),
                        "metrics_s": statistics.mean(t["metrics_s"] for t in timing),
                        "case_s": statistics.mean(t["case_s"] for t in timing),
                        "cpu_s": statistics.mean(t["cpu_s"] for t in timing),
                    }
                )
                shutil.rmtree(folder, ignore_errors=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    for workers in (1, 2):
        runs = [r for r in out["runs"] if r["workers"] == workers]
        fastest = min(runs, key=lambda r: r["wall_s"])
        out[f"w{workers}"] = {
            **fastest,
            "cases_per_min": 60 * cases / fastest["wall_s"],
            # what a case costs beyond its time stepping, all included (pool start,
            # FMU loading, reset, initialization, metrics, result files), per worker
            "overhead_per_case_s": fastest["wall_s"] * workers / cases - fastest["step_s"],
        }
    out["scaling_efficiency"] = out["w2"]["cases_per_min"] / (2 * out["w1"]["cases_per_min"])
    # the same from the workers' CPU time per case (what a case costs when the cores are not shared):
    # below 1 when two workers slow each other down (memory, caches, the driver)
    out["cpu_scaling_efficiency"] = min(r["cpu_s"] for r in out["runs"] if r["workers"] == 1) / min(
        r["cpu_s"] for r in out["runs"] if r["workers"] == 2
    )
    return out


def profile(ssp: str, stop: float) -> str:
    from mast.core.motion import SineMotion
    from mast.core.session import Session

    with Session(ssp) as session:
        session.run(SineMotion("z", 0.005, 5.0), 0.05, record=RECORD)
        prof = cProfile.Profile()
        prof.enable()
        session.run(SineMotion("z", 0.005, 5.0), stop, record=RECORD)
        prof.disable()
    text = io.StringIO()
    pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(18)
    return text.getvalue()


def _print_single(single: dict, stop: float, repeats: int, ms) -> None:
    print(f"one run, z sine 5 mm at 5 Hz, {stop:g} s simulated (min of {repeats}):")
    print(f"  FMU co-simulation, stepping   {ms(single['fmu_step_s'])}   real-time factor {single['rtf_fmu']:.2f}")
    print(
        f"  direct composition, stepping  {ms(single['direct_step_s'])}   real-time factor {single['rtf_direct']:.2f}"
    )
    for key, label in (
        ("fmu", "FMU co-simulation"),
        ("fmu_fmpy_calls", "FMU, Python loop, fmpy calls"),
        ("direct", "direct composition"),
    ):
        print(
            f"  {label:28s} physics {ms(single[key + '_physics_s'])}, plumbing {ms(single[key + '_plumbing_s'])}"
            f" = {single[key + '_plumbing_over_physics']:.2f} x physics"
        )
    print(
        f"  initialization {ms(single['fmu_init_s'])}, session reset {ms(single['fmu_setup_s'])}; "
        f"simulate() without reuse adds {ms(single['simulate_overhead_s'])} (extract, load, instantiate, free)"
    )


def _print_batch(batch: dict, ms) -> None:
    print(
        f"batch of {batch['cases']} cases of {batch['stop_time_s']:g} s (min of {len(batch['runs']) // 2} interleaved):"
    )
    for w in (1, 2):
        b = batch[f"w{w}"]
        print(
            f"  {w} worker(s): {b['wall_s']:6.2f} s  {b['cases_per_min']:6.1f} cases/min  "
            f"overhead/case {ms(b['overhead_per_case_s'])} (step {ms(b['step_s'])}, init {ms(b['init_s'])}, "
            f"reset {ms(b['setup_s'])}, metrics {ms(b['metrics_s'])}, first load {ms(b['first_setup_s'])})"
        )
    print(
        f"  scaling efficiency 2 vs 1 worker: {100 * batch['scaling_efficiency']:.1f} % by throughput, "
        f"{100 * batch['cpu_scaling_efficiency']:.1f} % by CPU time per case"
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ssp", default=str(default_build_dir() / "ssp" / "MAST.ssp"))
    parser.add_argument("--cases", type=int, default=24)
    parser.add_argument("--stop-time", type=float, default=1.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", help="also write the figures to this file")
    parser.add_argument("--profile", action="store_true", help="cProfile of one run, by own time")
    parser.add_argument("--skip-batch", action="store_true", help="only the single-run figures")
    parser.add_argument("--skip-single", action="store_true", help="only the batch figures")
    args = parser.parse_args(argv)
    if not Path(args.ssp).exists():
        print(f"error: {args.ssp} does not exist: run `mast build`", file=sys.stderr)
        return 2
    ms = lambda s: f"{1e3 * s:7.1f} ms"  # noqa: E731
    result: dict = {}
    if not args.skip_single:
        result["single_run"] = single_run(args.ssp, args.stop_time, args.repeats + 2)
        _print_single(result["single_run"], args.stop_time, args.repeats + 2, ms)
    if not args.skip_batch:
        result["batch"] = batch_runs(args.ssp, args.cases, args.stop_time, args.repeats)
        _print_batch(result["batch"], ms)
    if args.profile:
        print(profile(args.ssp, args.stop_time))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
