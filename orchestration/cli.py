"""The ``mast`` command line: build, validate, run, bench."""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DEFAULT_SSP = REPO / "build" / "ssp" / "MAST.ssp"


class Progress:
    """A progress bar on stderr: redrawn in place on a terminal, a line every 10 % in logs."""

    def __init__(self, label: str) -> None:
        self.label = label
        self.last = -1
        self.granularity = 1 if sys.stderr.isatty() else 10

    def __call__(self, fraction: float) -> None:
        percent = int(fraction * 100) // self.granularity * self.granularity
        if percent != self.last:
            self.last = percent
            bar = "#" * (percent // 4)
            sys.stderr.write(f"\r{self.label} [{bar:<25}] {percent:3d}%")
            if percent >= 100 or self.granularity > 1:
                sys.stderr.write("\n")
            sys.stderr.flush()


def cmd_build(args) -> int:
    from .build import build_all

    build_all(Path(args.out))
    return 0


def validate_all(build_dir: Path) -> list[str]:
    """Problems found in the built FMUs (fmpy validation) and SSPs (SSP 1.0 schema)."""
    from fmpy.validation import validate_fmu

    from .ssp import safe_extract, validate_ssd_schema

    problems = []
    fmus = sorted((build_dir / "fmus").glob("*.fmu"))
    ssps = sorted((build_dir / "ssp").glob("*.ssp"))
    if not fmus or not ssps:
        problems.append(f"{build_dir}: nothing built yet (run `mast build`)")
    for fmu in fmus:
        problems += [f"{fmu.name}: {p}" for p in validate_fmu(str(fmu))]
    for ssp in ssps:
        with tempfile.TemporaryDirectory() as tmp:
            safe_extract(ssp, tmp)
            problems += [f"{ssp.name}: {p}" for p in validate_ssd_schema(Path(tmp) / "SystemStructure.ssd")]
    return problems


def cmd_validate(args) -> int:
    problems = validate_all(Path(args.build))
    for p in problems:
        print(p)
    print("validation: no problems" if not problems else f"validation: {len(problems)} problem(s)")
    return 1 if problems else 0


def cmd_run(args) -> int:
    from .master import SimulationError
    from .run import motion_from_cli, parse_overrides, simulate, write_outputs

    motion = motion_from_cli(args.motion, args.amplitude, args.frequency)
    out = Path(args.out)
    try:
        result = simulate(args.ssp, motion, args.stop_time, parameters=parse_overrides(args.set or []),
                          record=args.record, record_step=args.record_step, direct=args.direct,
                          progress=Progress("co-simulation"))
        failed = None
    except SimulationError as err:
        result, failed = err.result, str(err)
    summary = write_outputs(result, out, args.stop_time, motion)
    print(json.dumps({k: summary[k] for k in ("wall_time_s", "real_time_factor") if k in summary}))
    if failed:
        print(f"error: {failed} (results up to the failure are in {out})", file=sys.stderr)
        return 2
    print(f"wrote {out / 'results.csv'}, {out / 'summary.json'}, {out / 'motion.png'}")
    return 0


def cmd_fit_gains(args) -> int:
    from .identify import main as fit_main

    fit = fit_main(args.ssp, Path(args.out) if args.out else None, args.workers)
    print("gains: " + ", ".join(f"{k} = {v:.6g}" for k, v in fit.gains.items()))
    for f, (mag, ph) in fit.responses.items():
        print(f"  {f:g} Hz: magnitude {100 * mag:.1f} %, phase {ph:.1f} deg")
    print(f"scaled cost {fit.cost:.4f} ({fit.evaluations} evaluations, {fit.wall_time_s:.0f} s)")
    return 0


def cmd_reproduce(args) -> int:
    from .reproduce import reproduce

    summary = reproduce(args.ssp, Path(args.out), workers=args.workers, direct=args.direct)
    print(f"{summary['within']} of {summary['judged']} judged rows within the paper's deviation; "
          f"{summary['runs']} co-simulations in {summary['wall_time_s']:.0f} s; wrote {Path(args.out) / 'report.md'}")
    return 1 if summary["failures"] else 0


def cmd_bench(args) -> int:
    from .bench import main as bench_main

    return bench_main(args)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="mast", description="MAST co-simulation: FMUs, SSP and master")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("build", help="build build/fmus/*.fmu and build/ssp/*.ssp from fmus/ and ssp/")
    p.add_argument("--out", default=str(REPO / "build"))
    p.set_defaults(func=cmd_build)

    p = sub.add_parser("validate", help="fmpy validation of every FMU and SSP 1.0 schema check of every SSD")
    p.add_argument("--build", default=str(REPO / "build"))
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("run", help="run a co-simulation with a sine pose command around the home pose")
    p.add_argument("ssp", nargs="?", default=str(DEFAULT_SSP))
    p.add_argument("--motion", choices=("z", "psi", "theta"), default="z")
    p.add_argument("--amplitude", type=float, default=0.01, help="metres for z, degrees for psi and theta")
    p.add_argument("--frequency", type=float, default=1.0, help="Hz")
    p.add_argument("--stop-time", type=float, default=2.0, help="s")
    p.add_argument("--set", action="append", metavar="ELEMENT.PARAMETER=VALUE", help="override a parameter (repeatable)")
    p.add_argument("--record", action="append", metavar="ELEMENT.CONNECTOR",
                   help="signal to record (repeatable; default: every system input and declared output)")
    p.add_argument("--record-step", type=float, default=1e-3, help="s between recorded samples")
    p.add_argument("--direct", action="store_true", help="run the model objects directly (no FMI), same schedule")
    p.add_argument("--out", default="results")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("fit-gains", help="identify k_v, k_p, k_i from the paper's reported position responses")
    p.add_argument("ssp", nargs="?", default=str(DEFAULT_SSP))
    p.add_argument("--out", help="write the fitted gains as an .ssv parameter set")
    p.add_argument("--workers", type=int, default=2)
    p.set_defaults(func=cmd_fit_gains)

    p = sub.add_parser("reproduce", help="regenerate the paper's analyses: DIR/report.md, figures, paper_table.json")
    p.add_argument("ssp", nargs="?", default=str(DEFAULT_SSP))
    p.add_argument("--out", default="results/reproduce")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--direct", action="store_true", help="run the model objects without FMI (same numbers, faster)")
    p.set_defaults(func=cmd_reproduce)

    p = sub.add_parser("bench", help="real-time factor of the default system, FMU co-simulation vs direct composition")
    p.add_argument("ssp", nargs="?", default=str(DEFAULT_SSP))
    p.add_argument("--stop-time", type=float, default=10.0)
    p.add_argument("--profile", action="store_true", help="print where the time goes (cProfile of the direct run)")
    p.set_defaults(func=cmd_bench)

    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, FileNotFoundError, RuntimeError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
