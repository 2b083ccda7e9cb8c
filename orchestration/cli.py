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

    build_all(Path(args.out), fmi3=args.fmi3)
    return 0


def validate_all(build_dir: Path) -> list[str]:
    """Problems found in the built FMUs (fmpy validation) and SSPs (SSP 1.0 schema)."""
    from fmpy.validation import validate_fmu

    from .ssp import safe_extract, validate_ssd_schema

    problems = []
    fmus = sorted((build_dir / "fmus").glob("*.fmu"))
    ssps = sorted((build_dir / "ssp").glob("*.ssp"))
    fmus += sorted((build_dir / "fmus3").glob("*.fmu"))  # FMI 3.0 variants, if built (mast build --fmi3)
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

    summary = reproduce(args.ssp, Path(args.out), workers=args.workers, direct=not args.fmi)
    print(f"{summary['predictions_within']} of {summary['predictions']} predictions within the paper's tolerance "
          f"(fitted rows: {summary['fits_within']} of {summary['fits']}; reused fitted numbers: "
          f"{summary['reuses_within']} of {summary['reuses']}); {summary['runs']} co-simulations in "
          f"{summary['wall_time_s']:.0f} s; wrote {Path(args.out) / 'report.md'}")
    return 1 if summary["failures"] else 0


def cmd_hosts(args) -> int:
    from .hosts import HOSTS, cross_check

    rows = cross_check(args.ssp, args.stop_time, args.host or HOSTS)
    return 1 if any(row.get("failed") for row in rows) else 0


def cmd_bench(args) -> int:
    from .bench import main as bench_main

    return bench_main(args)


def cmd_synthesize(args) -> int:
    from .run import parse_overrides
    from .synthesize import DEFAULT_TESTS, parse_tests, synthesize

    def pairs(items, what):
        out = {}
        for item in items or []:
            key, sep, value = item.partition("=")
            if not sep:
                raise ValueError(f"--{what} {item!r}: expected SIGNAL=VALUE, e.g. tau_m=0.002")
            out[key.strip()] = float(value)
        return out

    synthesize(args.ssp, Path(args.out), parse_overrides(args.set or []),
               tests=parse_tests(args.tests) if args.tests else DEFAULT_TESTS,
               noise=pairs(args.noise, "noise"), resolution=pairs(args.resolution, "resolution"),
               torque_filter_s=args.torque_filter, sample_time=args.sample_time, seed=args.seed,
               direct=args.direct, workers=args.workers, truth_path=Path(args.truth) if args.truth else None)
    return 0


def cmd_diagnose(args) -> int:
    from .diagnosis import Options, diagnose

    doc = diagnose(Options(Path(args.measured), Path(args.out), args.ssp, model=args.model,
                           holdout=args.holdout.split(",") if args.holdout else None, workers=args.workers,
                           direct=not args.fmu))
    return 0 if doc["verdict"]["status"] != "unexplained residual" else 3


def cmd_check_mechanism(args) -> int:
    from .conformance import check_mechanism

    failed = 0
    for fmu in args.fmu:
        results = check_mechanism(fmu)
        print(f"{fmu}:")
        for c in results:
            print(f"  {c}")
        failed += sum(not c.passed for c in results)
    print("all checks passed" if not failed else f"{failed} check(s) failed")
    return 1 if failed else 0


def cmd_compare(args) -> int:
    from .compare import DEFAULT, QUICK, TestSet, compare
    from .frequency import CountProgress
    from .run import parse_overrides

    base = QUICK if args.quick else DEFAULT
    test_set = TestSet(tuple(args.motions) if args.motions else base.axes,
                       tuple(args.frequencies) if args.frequencies else base.frequencies, base.amplitudes)
    comp = compare(args.mechanism or (), Path(args.out), test_set, workers=args.workers, direct=args.direct,
                   parameters=parse_overrides(args.set or []), base_ssd=args.ssd, fmu_dir=args.fmus,
                   progress=CountProgress("compare"), controllers=args.controller or (), payload=args.payload)
    print((Path(args.out) / "comparison.md").read_text(), end="")
    print(f"{sum(r['tests'] for r in comp.summary)} sine tests in {comp.wall_time_s:.0f} s; "
          f"wrote {', '.join(p.name for p in comp.files)} in {args.out}")
    return 1 if any(r["failed"] for r in comp.summary) else 0


def cmd_batch(args) -> int:
    from .batch.cli import main as batch_main

    return batch_main(args)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="mast", description="MAST co-simulation: FMUs, SSP and master")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("build", help="build build/fmus/*.fmu and build/ssp/*.ssp from fmus/ and ssp/")
    p.add_argument("--out", default=str(REPO / "build"))
    p.add_argument("--fmi3", action="store_true", help="also build the FMI 3.0 variants into OUT/fmus3 (pythonfmu3)")
    p.set_defaults(func=cmd_build)

    p = sub.add_parser("hosts", help="run an SSP in libcosim, ecospy and the ecos CLI; compare with this master")
    p.add_argument("ssp", nargs="?", default=str(REPO / "build" / "ssp" / "MAST_standalone.ssp"))
    p.add_argument("--stop-time", type=float, default=1.0)
    p.add_argument("--host", action="append", choices=("libcosim", "ecospy", "ecos"), help="(repeatable; default: all)")
    p.set_defaults(func=cmd_hosts)

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
    p.add_argument("--fmi", action="store_true",
                   help="run the SSP's FMUs through FMI (the same numbers to 1e-12, tests/test_cosim.py; about "
                        "twice the CPU time); the default runs the same components and schedule without FMI")
    p.set_defaults(func=cmd_reproduce)

    p = sub.add_parser("bench", help="real-time factor of the default system, FMU co-simulation vs direct composition")
    p.add_argument("ssp", nargs="?", default=str(DEFAULT_SSP))
    p.add_argument("--stop-time", type=float, default=10.0)
    p.add_argument("--profile", action="store_true", help="print where the time goes (cProfile of the direct run)")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("synthesize", help="synthetic measured data with a hidden effect (docs/measured-data.md)")
    p.add_argument("ssp", nargs="?", default=str(DEFAULT_SSP))
    p.add_argument("--out", required=True, help="measured-data folder to write (CSV per test + meta.json)")
    p.add_argument("--set", action="append", metavar="ELEMENT.PARAMETER=VALUE",
                   help="the truth: override a parameter (repeatable; 'actuator.X' sets X on every actuator)")
    p.add_argument("--noise", action="append", metavar="SIGNAL=STD",
                   help="white sensor noise: tau_m=0.002 (N.m, default), rho=0 (m, default)")
    p.add_argument("--resolution", action="append", metavar="SIGNAL=STEP", help="encoder quantisation: rho=1e-6 (m, default)")
    p.add_argument("--torque-filter", type=float, default=5e-4, help="the drive's torque low-pass time constant [s]")
    p.add_argument("--sample-time", type=float, default=1e-3, help="log sampling step [s]")
    p.add_argument("--tests", help="MOTION:AMPLITUDE:FREQUENCY[,...] (m for z, degrees for psi/theta; default: 7 tests)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--truth", help="where to write the truth (default: next to the folder, DIR.truth.json)")
    p.add_argument("--direct", action="store_true", help="run the model objects without FMI (same numbers, faster)")
    p.add_argument("--workers", type=int, default=2)
    p.set_defaults(func=cmd_synthesize)

    p = sub.add_parser("diagnose", help="name the effects missing from the model by comparing it with measured data "
                                        "(docs/diagnose.md)")
    p.add_argument("ssp", nargs="?", default=str(DEFAULT_SSP))
    p.add_argument("--measured", required=True, help="measured-data folder (docs/measured-data.md)")
    p.add_argument("--out", required=True, help="folder for diagnosis.json, report.md, figures, the augmented model")
    p.add_argument("--model", help="nominal actuator parameter set: an .ssv file or the name of one in the SSP "
                                   "(default: the SSP's bindings, i.e. the manufacturer data)")
    p.add_argument("--holdout", help="comma-separated test names to hold out (default: meta.json roles, else every "
                                     "second test in frequency order)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--fmu", action="store_true", help="simulate through the FMUs (default: the direct composition, "
                                                      "the same numbers to 1e-12, about twice as fast)")
    p.set_defaults(func=cmd_diagnose)

    p = sub.add_parser("check-mechanism", help="black-box checks a mechanism FMU must pass to plug in (docs/interfaces.md)")
    p.add_argument("fmu", nargs="+", help="mechanism FMU(s)")
    p.set_defaults(func=cmd_check_mechanism)

    from .compare import PAYLOAD_MISMATCH_KG

    p = sub.add_parser("compare", help="run one sine test set on several mechanism designs or controllers: table and "
                                       "plots (docs/designs, docs/controller.md)")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--mechanism", nargs="+", metavar="FMU_OR_SSP",
                       help="mechanism FMUs to swap into the base system (or whole systems, .ssp/.ssd)")
    which.add_argument("--controller", nargs="+", metavar="NAME_FMU_OR_SSP",
                       help="controllers: joint, workspace, feedforward, computed_torque, controller FMUs to swap into "
                            "the base system, or whole systems (.ssp/.ssd)")
    p.add_argument("--payload", type=float, default=PAYLOAD_MISMATCH_KG, metavar="KG",
                   help="with --controller: also run every test with this payload on the platform, unknown to the "
                        f"controllers (default {PAYLOAD_MISMATCH_KG:g} kg; 0: no robustness runs)")
    p.add_argument("--out", required=True, help="folder for comparison.csv/.json/.md, runs.csv, the plots, systems/")
    p.add_argument("--quick", action="store_true", help="the small test set: z motion at 1, 4 and 8 Hz")
    p.add_argument("--motions", nargs="+", choices=("z", "psi", "theta"), help="motions to test (default: all three)")
    p.add_argument("--frequencies", nargs="+", type=float, metavar="HZ", help="test frequencies (default: 0.5 to 10 Hz)")
    p.add_argument("--set", action="append", metavar="ELEMENT.PARAMETER=VALUE", help="override a parameter in every design")
    p.add_argument("--workers", type=int, help="parallel processes (default: the number of cores)")
    p.add_argument("--direct", action="store_true", help="run the model objects without FMI (this project's FMUs only)")
    p.add_argument("--ssd", default=str(REPO / "ssp" / "MAST.ssd"), help="base system the FMUs are swapped into")
    p.add_argument("--fmus", default=str(REPO / "build" / "fmus"), help="FMUs of the base system's other components")
    p.set_defaults(func=cmd_compare)

    p = sub.add_parser("batch", help="run the cases of a batch config (TOML/YAML) in parallel: docs/batch.md")
    p.add_argument("config", help="batch config: .toml, .yaml or .json")
    p.add_argument("--out", required=True, help="folder for the results (manifest, per-case files, tables, plots)")
    p.add_argument("--workers", type=int, help="local worker processes (default: the number of cores)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="run on this Dask scheduler (tcp://host:8786) instead")
    p.add_argument("--resume", action="store_true", help="go on with the batch in --out: skip its finished cases")
    p.add_argument("--retry-failed", action="store_true", help="with --resume: run failed and crashed cases again")
    p.add_argument("--dry-run", action="store_true", help="list the cases and stop")
    p.add_argument("--no-plots", action="store_true", help="write no figures")
    p.set_defaults(func=cmd_batch)

    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, FileNotFoundError, RuntimeError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
