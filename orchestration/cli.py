"""The ``mast`` command line: build, validate, run, bench."""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Optional, Union

from fmus.mechanism.topology import POSE

from .core.build import default_build_dir

if TYPE_CHECKING:
    from .core.specimen import Specimen

REPO = Path(__file__).resolve().parents[1]
BUILD = default_build_dir()  # build/ of the checkout, or of the current directory after a plain install
DEFAULT_SSP = BUILD / "ssp" / "MAST.ssp"


def _positive(what: str):
    """An argparse type: a positive, finite number of ``what`` (inf, nan, 0 and negatives are refused)."""

    def parse(text: str) -> float:
        value = _number(text)
        if not value > 0 or not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{text!r}: expected a positive, finite number of {what}")
        return value

    return parse


seconds = _positive("seconds")
hertz = _positive("Hz")


def finite(text: str) -> float:
    """argparse type: a finite number."""
    value = _number(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r}: expected a finite number")
    return value


def share(text: str) -> float:
    """argparse type: a fraction strictly between 0 and 1."""
    value = finite(text)
    if not 0 < value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a fraction between 0 and 1 (exclusive)")
    return value


def nonnegative(text: str) -> float:
    """argparse type: a finite number >= 0."""
    value = finite(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a number >= 0")
    return value


def count(text: str) -> int:
    """argparse type: a whole number >= 1 (workers)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a whole number >= 1") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a whole number >= 1")
    return value


def folder(text: str) -> str:
    """argparse type: an output folder, which may exist but must not be a file (checked before any run)."""
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is an existing file; expected a folder (new or existing)")
    for parent in path.absolute().parents:
        if parent.exists():
            if not parent.is_dir():
                raise argparse.ArgumentTypeError(f"{text!r}: {parent} is a file, so the folder cannot be made")
            break
    return text


def animate_folder(text: str) -> str:
    """argparse type: `mast animate`'s output folder; a page's name (the option's former meaning) is refused with
    the new form."""
    if text.lower().endswith((".html", ".htm")):
        from .analyses.animate import PAGE

        raise argparse.ArgumentTypeError(
            f"{text!r}: --out names a folder, like every --out (it named the page before): "
            f"mast animate RUN_DIR --out DIR writes DIR/{PAGE}"
        )
    return folder(text)


def specimen(text: str) -> Specimen:
    """argparse type: ``--specimen MASS[,X,Y,Z[,IXX,IYY,IZZ[,IXY,IXZ,IYZ]]]`` or ``FILE.toml`` (core.specimen.parse),
    checked physical."""
    from .core.specimen import SpecimenError, parse

    try:
        return parse(text)
    except SpecimenError as err:  # argparse names the option itself
        raise argparse.ArgumentTypeError(str(err).removeprefix("--specimen ")) from None


SPECIMEN_HELP = (
    "a specimen bolted to the table: MASS[,X,Y,Z[,IXX,IYY,IZZ[,IXY,IXZ,IYZ]]]: mass in kg, its centre of mass "
    "from the platform centre P in m (platform axes, z up), its inertia about the centre of mass in kg m^2 "
    "(platform axes; what is left out is 0), or FILE.toml (keys mass, com, inertia); the mechanism's payload "
    "parameters (as --set mechanism.m_payload=...), refused (exit 2) if not physical or if a drive cannot hold it "
    "at rest at the home pose (docs/specimens.md)"
)


def add_specimen(p: argparse.ArgumentParser, text: str = SPECIMEN_HELP) -> None:
    """The ``--specimen`` option every command that runs the mechanism shares."""
    p.add_argument("--specimen", type=specimen, metavar="MASS[,X,Y,Z[,IXX,...]]|FILE.toml", help=text)


def specimen_overrides(
    args: argparse.Namespace, overrides: Optional[dict], *systems: Union[str, Path, tuple[Path, dict]]
) -> Optional[dict]:
    """``overrides`` with ``args.specimen`` on the mechanism, once the drives of every system are found to hold it at
    rest at home (``analyses.specimen.check_held``); a system is a path (.ssp/.ssd) or (path, the parameters of a
    mechanism FMU swapped into it)."""
    if args.specimen is None:
        return overrides
    from .analyses.specimen import check_held, held_text
    from .core.specimen import with_specimen

    merged = with_specimen(overrides, args.specimen)
    for system in systems:
        ssp, mechanism = system if isinstance(system, tuple) else (system, None)
        print(held_text(check_held(ssp, args.specimen, merged, mechanism)))
    return merged


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


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
    from .core.build import SSP_SRC, build_all

    build_all(Path(args.out), fmi3=args.fmi3)
    if args.native:
        from .core.native.build import build_native_all

        platforms = ("linux64", "aarch64-linux", "win64", "darwin64") if args.cross else ("linux64",)
        build_native_all(Path(args.out), sorted(SSP_SRC.glob("*.ssd")), platforms=platforms)
    return 0


def validate_all(build_dir: Path) -> list[str]:
    """Problems found in the built FMUs (fmpy validation) and SSPs (SSP 1.0 schema)."""
    from fmpy.validation import validate_fmu

    from .core.ssp import check_archive, safe_extract, validate_ssd_schema
    from .core.ssv import SSPFormatError

    problems = []
    fmus = sorted((build_dir / "fmus").glob("*.fmu"))
    ssps = sorted((build_dir / "ssp").glob("*.ssp"))
    fmus += sorted((build_dir / "fmus3").glob("*.fmu"))  # FMI 3.0 variants, if built (mast build --fmi3)
    fmus += sorted((build_dir / "fmus" / "native").glob("*.fmu"))  # native FMUs, if built (mast build --native)
    ssps += sorted((build_dir / "ssp" / "native").glob("*.ssp"))
    if not fmus or not ssps:
        problems.append(f"{build_dir}: nothing built yet (run `mast build`)")
    for fmu in fmus:
        try:  # what every reader of ours refuses (an entry leaving its folder, a zip bomb), fmpy does not look for
            check_archive(fmu, fmu.name)
        except SSPFormatError as err:
            problems.append(str(err))
            continue
        problems += [f"{fmu.name}: {p}" for p in validate_fmu(str(fmu))]
    for ssp in ssps:
        with tempfile.TemporaryDirectory() as tmp:
            try:
                safe_extract(ssp, tmp, ssp.name)
            except SSPFormatError as err:
                problems.append(str(err))
                continue
            problems += [f"{ssp.name}: {p}" for p in validate_ssd_schema(Path(tmp) / "SystemStructure.ssd")]
    return problems


def cmd_validate(args) -> int:
    problems = validate_all(Path(args.build))
    for p in problems:
        print(p)
    print("validation: no problems" if not problems else f"validation: {len(problems)} problem(s)")
    return 1 if problems else 0


def cmd_run(args) -> int:
    from .core.master import SimulationError
    from .core.motion import system_axes
    from .core.run import motion_from_cli, parse_overrides, simulate, write_outputs
    from .core.ssp import SSPArchive

    out = Path(args.out)
    ssp = args.ssp
    if args.native:
        from .analyses.bench import native_variant

        ssp = native_variant(args.ssp)
        if ssp is None:
            print(
                f"error: no native variant of {args.ssp} (build/ssp/native/...): run `mast build --native`",
                file=sys.stderr,
            )
            return 2
    overrides = specimen_overrides(args, parse_overrides(args.set or []), ssp)
    with SSPArchive(ssp) as archive:  # --motion: a coordinate of the system's mechanism (its topology)
        axes = system_axes(archive.system, overrides)
    motion = motion_from_cli(args.motion, args.amplitude, args.frequency, axes, str(ssp))
    try:
        result = simulate(
            ssp,
            motion,
            args.stop_time,
            parameters=overrides,
            record=args.record,
            record_step=args.record_step,
            direct=args.direct,
            progress=Progress("co-simulation"),
        )
        failed = None
    except SimulationError as err:
        result, failed = err.result, str(err)
    summary = write_outputs(result, out, args.stop_time, motion, ssp)
    print(json.dumps({k: summary[k] for k in ("wall_time_s", "real_time_factor") if k in summary}))
    if failed:
        print(f"error: {failed} (results up to the failure are in {out})", file=sys.stderr)
        return 2
    sized = _size_in_summary(out, summary)
    print(f"wrote {out / 'results.csv'}, {out / 'summary.json'}, {out / 'motion.png'}{sized}")
    return 0


def _size_in_summary(out: Path, summary: dict) -> str:
    """The run's drive sizing (mast sizing) beside it and its verdict in summary.json; what was written, for the
    message. A system without ratings is run all the same: the summary then says why it has no verdict."""
    from .analyses.sizing import SizingError, size_run
    from .analyses.sizing import write as write_sizing
    from .core.atomic import atomic_write

    try:
        doc, sized = size_run(out)
    except SizingError as err:
        summary["sizing"] = {"verdict": None, "why": str(err)}
        atomic_write(out / "summary.json", json.dumps(summary, indent=2).encode())
        return ""
    files = write_sizing(doc, sized, out)
    summary["sizing"] = {"verdict": doc["verdict"], "limiting": doc["limiting"]}
    atomic_write(out / "summary.json", json.dumps(summary, indent=2).encode())
    print(
        f"sizing: {doc['verdict']}; limiting {doc['limiting']['drive']} {doc['limiting']['component']} "
        f"{doc['limiting']['item']}, margin {100 * doc['limiting']['margin']:.1f} %"
    )
    return ", " + ", ".join(str(f) for f in files)


def cmd_fit_gains(args) -> int:
    from .analyses.identify import gains_file
    from .analyses.identify import main as fit_main

    fit = fit_main(args.ssp, Path(args.out) if args.out else None, args.workers)
    print("gains: " + ", ".join(f"{k} = {v:.6g}" for k, v in fit.gains.items()))
    for f, (mag, ph) in fit.responses.items():
        print(f"  {f:g} Hz: magnitude {100 * mag:.1f} %, phase {ph:.1f} deg")
    print(
        f"scaled cost {fit.cost:.4f} ({fit.evaluations} evaluations, {fit.wall_time_s:.0f} s)"
        + (f"; wrote {gains_file(Path(args.out))}" if args.out else "")
    )
    return 0


def cmd_reproduce(args) -> int:
    from .analyses.reproduce import reproduce

    summary = reproduce(args.ssp, Path(args.out), workers=args.workers, direct=not args.fmi)
    print(
        f"{summary['predictions_within']} of {summary['predictions']} predictions within the paper's tolerance "
        f"(fitted rows: {summary['fits_within']} of {summary['fits']}; reused fitted numbers: "
        f"{summary['reuses_within']} of {summary['reuses']}); {summary['runs']} co-simulations in "
        f"{summary['wall_time_s']:.0f} s; wrote {Path(args.out) / 'report.md'}"
    )
    return 1 if summary["failures"] else 0


def cmd_hosts(args) -> int:
    from .hosts.cosim import HOSTS, compared_signals, cross_check, show

    if args.show:
        print(show(args.show, args.ssp, args.stop_time, list(compared_signals(args.ssp)), Path.cwd()))
        return 0
    rows = cross_check(args.ssp, args.stop_time, args.host or HOSTS)
    return 1 if any(row.get("failed") for row in rows) else 0


def cmd_bench(args) -> int:
    from .analyses.bench import main as bench_main

    return bench_main(args)


def cmd_synthesize(args) -> int:
    from .analyses.synthesize import DEFAULT_TESTS, parse_tests, synthesize
    from .core.run import parse_overrides

    def pairs(items, what):
        out = {}
        for item in items or []:
            key, sep, value = item.partition("=")
            try:
                number = float(value) if sep else math.nan
            except ValueError:
                number = math.nan
            if not sep or not math.isfinite(number) or number < 0:
                raise ValueError(f"--{what} {item!r}: expected SIGNAL=VALUE with a finite VALUE >= 0, e.g. tau_m=0.002")
            out[key.strip()] = number
        return out

    synthesize(
        args.ssp,
        Path(args.out),
        specimen_overrides(args, parse_overrides(args.set or []), args.ssp),
        tests=parse_tests(args.tests) if args.tests else DEFAULT_TESTS,
        noise=pairs(args.noise, "noise"),
        resolution=pairs(args.resolution, "resolution"),
        torque_filter_s=args.torque_filter,
        sample_time=args.sample_time,
        seed=args.seed,
        direct=args.direct,
        workers=args.workers,
        truth_path=Path(args.truth_out) / f"{Path(args.out).name}.truth.json" if args.truth_out else None,
    )
    return 0


def cmd_diagnose(args) -> int:
    from .analyses.bench import native_variant
    from .data.record import is_record_folder
    from .diagnosis import Options, diagnose

    if sum(map(bool, (args.fmu, args.direct, args.native))) > 1:
        print("error: --fmu, --direct and --native are alternatives: give one", file=sys.stderr)
        return 2
    # default: the native variant where it is built (a MAST measured-data folder), else the direct composition
    native = args.native or (
        not args.fmu
        and not args.direct
        and not is_record_folder(Path(args.measured))
        and native_variant(args.ssp) is not None
    )
    doc = diagnose(
        Options(
            Path(args.measured),
            Path(args.out),
            args.ssp,
            parameters=specimen_overrides(args, {}, args.ssp),
            model=args.model,
            holdout=args.holdout.split(",") if args.holdout else None,
            workers=args.workers,
            direct=not args.fmu,
            native=native,
            holdout_fraction=args.holdout_fraction,
        )
    )
    return 0 if doc["verdict"]["status"] != "unexplained residual" else 3


def cmd_import(args) -> int:
    from .data.importer import import_file

    summary = import_file(args.file, args.map, args.out)
    for warning in summary["warnings"]:
        print(f"import: warning: {warning}", file=sys.stderr)
    print(
        f"import: {summary['samples']} samples every {summary['sample_time_s']:.6g} s "
        f"({summary['duration_s']:.6g} s), signals {', '.join(f'{k} ({v})' for k, v in summary['signals'].items())} "
        f"-> {summary['folder']}"
    )
    return 0


def cmd_replay(args) -> int:
    from .analyses.replay import replay
    from .core.run import parse_overrides

    doc = replay(args.ssp, args.measured, args.out, parse_overrides(args.set or []), direct=not args.fmu)
    for name, s in doc["signals"].items():
        print(f"replay: {name} ({s['kind']}): relative error {s['relative_error_pct']:.4g} %, fit {s['fit_pct']:.4g} %")
    print(f"replay: wrote {Path(args.out) / 'replay.json'}")
    return 0


def cmd_check_mechanism(args) -> int:
    from .core.ssp import check_archive
    from .hosts.conformance import check_mechanism

    missing = [fmu for fmu in args.fmu if not Path(fmu).is_file()]
    if missing:
        raise FileNotFoundError(f"{', '.join(missing)}: no such FMU file")
    for fmu in args.fmu:  # a truncated zip or an entry leaving its folder: one line here, not the child's traceback
        check_archive(fmu)
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
    from .analyses.compare import DEFAULT, QUICK, WORKSPACE_GRID, WORKSPACE_GRID_QUICK, TestSet, compare
    from .analyses.frequency import CountProgress
    from .core.run import parse_overrides

    base = QUICK if args.quick else DEFAULT
    test_set = TestSet(
        tuple(args.motions) if args.motions else base.axes,
        tuple(args.frequencies) if args.frequencies else base.frequencies,
        base.amplitudes,
    )
    systems = []  # what runs: a system, a mechanism FMU in the base system, a controller in it
    if args.specimen is not None:
        from .analyses.workspace import described
        from .core.components import fmu_parameters

        for item in args.mechanism or args.controller:
            path = Path(item)
            if path.suffix in (".ssp", ".ssd"):
                systems.append(path)
            elif path.suffix == ".fmu" and args.mechanism:
                systems.append((Path(args.ssd), fmu_parameters(path)))
            elif not (args.mechanism and described(item)) and Path(args.ssd) not in systems:
                systems.append(Path(args.ssd))
    parameters = specimen_overrides(args, parse_overrides(args.set or []), *systems)
    comp = compare(
        args.mechanism or (),
        Path(args.out),
        test_set,
        workers=args.workers,
        direct=args.direct,
        parameters=parameters,
        base_ssd=args.ssd,
        fmu_dir=args.fmus,
        progress=CountProgress("compare"),
        controllers=args.controller or (),
        payload=args.payload,
        workspace_grid=WORKSPACE_GRID_QUICK if args.quick else WORKSPACE_GRID,
    )
    print((Path(args.out) / "comparison.md").read_text(), end="")
    print(
        f"{sum(r['tests'] for r in comp.summary)} sine tests in {comp.wall_time_s:.0f} s; "
        f"wrote {', '.join(p.name for p in comp.files)} in {args.out}"
    )
    return 1 if any(r["failed"] for r in comp.summary) else 0


def cmd_workspace(args) -> int:
    import math

    from .analyses.workspace import classify, compute, machine, parse_pose, summarize, sweep_for_pose, unit_text, write

    if not args.out and not args.pose:
        raise ValueError(
            "workspace: give --out DIR (the whole workspace) or --pose Z,PSI_DEG,THETA_DEG (one pose: one "
            "number per coordinate of the mechanism, m or deg)"
        )
    m = machine(args.design, args.payload)
    sweep = args.sweep.split(",") if args.sweep else None
    pose = parse_pose(args.pose, m.topology) if args.pose else None
    if pose is not None and sweep is None:
        sweep = sweep_for_pose(m.topology, pose)
    ws = compute(
        m, args.step_z, math.radians(args.step_tilt), progress=Progress(f"workspace of {m.label}"), sweep=sweep
    )
    if args.out:
        files = write(ws, Path(args.out), plots=not args.no_plots)
        s = summarize(ws)
        through = ", ".join(
            f"{name[:-4]} {lo:.3g}..{hi:.3g} deg" if name.endswith("_deg") else f"{name[:-2]} {lo:.4g}..{hi:.4g} m"
            for name, (lo, hi) in s["ranges_through_home"].items()
        )
        volume = [k for k in s if k.startswith("volume_")]  # in m and rad, then in m and deg (if angles)
        shown = [f"{s[k]:.4g} {unit_text(k[len('volume_') :])}" for k in volume]
        print(
            f"{m.label}: {s['poses_inside']} poses inside, volume {shown[-1]}"
            + (f" ({shown[0]})" if len(shown) > 1 else "")
            + f"; through home {through}; "
            f"smallest margin {s['smallest_margin']['value']:.3g} m/m, worst dexterity "
            f"{s['worst_dexterity']['value']:.3g}"
        )
        print(f"wrote {', '.join(str(f) for f in files)}")
    if pose is None:
        return 0
    answer = classify(ws, pose)
    print(json.dumps(answer, indent=2))
    return 0 if answer["inside"] else 1


def cmd_animate(args) -> int:
    from .analyses.animate import PAGE, write

    done = write(args.run_dir, Path(args.out or args.run_dir) / PAGE, args.fps)
    print(
        f"wrote {done['out']}: {done['frames']} frames ({done['fps']:g} per simulated second over "
        f"{done['simulated_s']:.3g} s), {done['bytes'] / 1e6:.2f} MB, in {done['seconds']:.2f} s"
    )
    return 0


def cmd_sizing(args) -> int:
    from .analyses.sizing import size_run, table, write
    from .core.run import parse_overrides

    overrides = parse_overrides(args.set) if args.set else None
    held = None
    if args.specimen is not None:  # its static hold, checked before the run is sized
        from .analyses.sizing import run_system
        from .analyses.specimen import check_held, held_text

        _, ssp, parameters = run_system(args.run_dir, args.ssp, overrides, args.specimen)
        held = check_held(ssp, args.specimen, parameters)
        print(held_text(held))
    doc, sized = size_run(args.run_dir, args.ssp, overrides, args.specimen)
    if held is not None:
        doc["specimen"] = held
    files = write(doc, sized, Path(args.out or args.run_dir), plots=not args.no_plots)
    print(table(doc), end="")
    print(f"wrote {', '.join(str(f) for f in files)}")
    return {"pass": 0, "at limit": 0}.get(doc["verdict"], 1)


def cmd_batch(args) -> int:
    from .batch.cli import main as batch_main

    return batch_main(args)


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """``--help`` with every default shown: appended as "(default: ...)" unless the help text states it already
    (it says "default"), or the default is None or False (an option that is off unless given)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "default" in text or action.default in (None, False, argparse.SUPPRESS):
            return text
        return super()._get_help_string(action)


class Renamed(argparse.Action):
    """An option spelling that was renamed: refused at once (exit 2), with a message that names the new one."""

    def __init__(self, option_strings, dest, instead: str, **kwargs) -> None:
        super().__init__(option_strings, dest, nargs="?", help=argparse.SUPPRESS, **kwargs)
        self.instead = instead

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        parser.error(f"{option_string} was renamed: {self.instead}")


SSP_HELP = "the built system (.ssp) to run"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="mast", description="MAST co-simulation: FMUs, SSP and master", formatter_class=HelpFormatter
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    sub.add_parser = functools.partial(sub.add_parser, formatter_class=HelpFormatter)

    p = sub.add_parser("build", help="build build/fmus/*.fmu and build/ssp/*.ssp from fmus/ and ssp/")
    p.add_argument("--out", type=folder, default=str(BUILD), help="build folder")
    p.add_argument("--fmi3", action="store_true", help="also build the FMI 3.0 variants into OUT/fmus3 (pythonfmu3)")
    p.add_argument(
        "--native",
        action="store_true",
        help="also build native FMUs (compiled C, no Python at run time) into OUT/fmus/native and the SSPs "
        "that bind them into OUT/ssp/native (needs a C compiler: docs/native.md)",
    )
    p.add_argument(
        "--cross",
        action="store_true",
        help="with --native: aarch64-linux, Windows and macOS (x86_64) binaries too, with zig (pip install "
        "ziglang); the Windows ones are run under Wine by the tests, the others only compiled "
        "(docs/native.md)",
    )
    p.set_defaults(func=cmd_build)

    p = sub.add_parser("hosts", help="run an SSP in libcosim, ecospy and the ecos CLI; compare with this master")
    p.add_argument(
        "ssp",
        nargs="?",
        default=str(BUILD / "ssp" / "MAST_standalone.ssp"),
        help="the built system (.ssp) to run; it must drive itself (a trajectory FMU: the hosts have no "
        "stimulus of ours)",
    )
    p.add_argument("--stop-time", type=seconds, default=1.0, help="s")
    p.add_argument(
        "--host", action="append", choices=("libcosim", "ecospy", "ecos"), help="host to run (repeatable; default: all)"
    )
    p.add_argument(
        "--show",
        choices=("ecospy", "ecos"),
        help="run nothing: print the environment (and the ecos command line, its csv.xml written here) "
        "to run the host by hand",
    )
    p.set_defaults(func=cmd_hosts)

    p = sub.add_parser("validate", help="fmpy validation of every FMU and SSP 1.0 schema check of every SSD")
    p.add_argument("--build", default=str(BUILD), help="build folder (mast build --out)")
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("run", help="run a co-simulation with a sine pose command around the home pose")
    p.add_argument("ssp", nargs="?", default=str(DEFAULT_SSP), help=SSP_HELP)
    p.add_argument(
        "--motion",
        choices=POSE,
        default="z",
        help="the axis of the sine: a coordinate of the system's mechanism (the 3PRS's: z, psi, theta)",
    )
    p.add_argument("--amplitude", type=finite, default=0.01, help="metres for x, y, z, degrees for the angles")
    p.add_argument("--frequency", type=hertz, default=1.0, help="Hz of the sine (positive)")
    p.add_argument("--stop-time", type=seconds, default=2.0, help="s")
    p.add_argument(
        "--set", action="append", metavar="ELEMENT.PARAMETER=VALUE", help="override a parameter (repeatable)"
    )
    add_specimen(p)
    p.add_argument(
        "--record",
        action="append",
        metavar="ELEMENT.CONNECTOR",
        help="signal to record (repeatable; default: every system input and declared output)",
    )
    p.add_argument("--record-step", type=seconds, default=1e-3, help="s between recorded samples")
    p.add_argument("--direct", action="store_true", help="run the model objects directly (no FMI), same schedule")
    p.add_argument(
        "--native",
        action="store_true",
        help="run the SSP's native variant (build/ssp/native/, mast build --native): compiled FMUs",
    )
    p.add_argument("--out", type=folder, default="results", help="folder for results.csv, summary.json, motion.png")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("fit-gains", help="identify k_v, k_p, k_i from the paper's reported position responses")
    p.add_argument("ssp", nargs="?", default=str(DEFAULT_SSP), help=SSP_HELP)
    p.add_argument(
        "--out",
        type=folder,
        help="folder for the fitted gains, an .ssv parameter set "
        "(controller_paper_reading_fit.ssv, the set mast reproduce binds; default: not written)",
    )
    p.add_argument("--workers", type=count, default=2, help="parallel processes")
    p.set_defaults(func=cmd_fit_gains)

    p = sub.add_parser("reproduce", help="regenerate the paper's analyses: DIR/report.md, figures, paper_table.json")
    p.add_argument("ssp", nargs="?", default=str(DEFAULT_SSP), help=SSP_HELP)
    p.add_argument(
        "--out", type=folder, default="results/reproduce", help="folder for report.md, the figures, paper_table.json"
    )
    p.add_argument("--workers", type=count, default=2, help="parallel processes")
    p.add_argument(
        "--fmi",
        action="store_true",
        help="run the SSP's FMUs through FMI (the same numbers to 1e-12, tests/test_cosim.py; about "
        "twice the CPU time); the default runs the same components and schedule without FMI",
    )
    p.set_defaults(func=cmd_reproduce)

    p = sub.add_parser("bench", help="real-time factor of the default system, FMU co-simulation vs direct composition")
    p.add_argument("ssp", nargs="?", default=str(DEFAULT_SSP), help=SSP_HELP)
    p.add_argument("--stop-time", type=seconds, default=10.0, help="s simulated")
    p.add_argument("--profile", action="store_true", help="print where the time goes (cProfile of the direct run)")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("synthesize", help="synthetic measured data with a hidden effect (docs/measured-data.md)")
    p.add_argument("ssp", nargs="?", default=str(DEFAULT_SSP), help=SSP_HELP)
    p.add_argument("--out", type=folder, required=True, help="measured-data folder to write (CSV per test + meta.json)")
    p.add_argument(
        "--set",
        action="append",
        metavar="ELEMENT.PARAMETER=VALUE",
        help="the truth: override a parameter (repeatable; 'actuator.X' sets X on every actuator)",
    )
    add_specimen(p, "the truth's specimen: " + SPECIMEN_HELP)
    p.add_argument(
        "--noise",
        action="append",
        metavar="SIGNAL=STD",
        help="white sensor noise: tau_m=0.002 (N.m, default), rho=0 (m, default)",
    )
    p.add_argument(
        "--resolution", action="append", metavar="SIGNAL=STEP", help="encoder quantisation: rho=1e-6 (m, default)"
    )
    p.add_argument(
        "--torque-filter", type=nonnegative, default=5e-4, help="the drive's torque low-pass time constant [s]"
    )
    p.add_argument("--sample-time", type=seconds, default=1e-3, help="log sampling step [s]")
    p.add_argument(
        "--tests",
        help="MOTION:AMPLITUDE:FREQUENCY[,...] (a coordinate of the system: m for x, y, z, degrees for the angles; "
        "default: 7 tests of the 3PRS)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the noise")
    p.add_argument(
        "--truth-out",
        type=folder,
        metavar="DIR",
        help="folder for the truth, DIR/NAME.truth.json with NAME the --out folder's name (default: the folder "
        "that holds --out, so the truth lies next to the data)",
    )
    p.add_argument(
        "--truth",
        action=Renamed,
        instead="--truth-out DIR names a folder, like every --out: the truth goes to DIR/NAME.truth.json "
        "(NAME: the --out folder's name)",
    )
    p.add_argument("--direct", action="store_true", help="run the model objects without FMI (same numbers, faster)")
    p.add_argument("--workers", type=count, default=2, help="parallel processes")
    p.set_defaults(func=cmd_synthesize)

    p = sub.add_parser(
        "diagnose",
        help="name the effects missing from the model by comparing it with measured data (docs/diagnose.md)",
        epilog="exit status: 0 when the verdict explains the data (or nothing is missing), 3 when a "
        "residual stays unexplained (the results are written all the same), 2 on bad input",
    )
    p.add_argument("ssp", nargs="?", default=str(DEFAULT_SSP), help=SSP_HELP)
    p.add_argument(
        "--measured",
        required=True,
        help="measured-data folder, or a record folder from mast import (docs/measured-data.md)",
    )
    p.add_argument(
        "--out", type=folder, required=True, help="folder for diagnosis.json, report.md, figures, the augmented model"
    )
    p.add_argument(
        "--model",
        help="nominal actuator parameter set: an .ssv file or the name of one in the SSP "
        "(default: the SSP's bindings, i.e. the manufacturer data)",
    )
    add_specimen(p, "the specimen the measured machine carried, in the nominal model: " + SPECIMEN_HELP)
    p.add_argument(
        "--holdout",
        help="comma-separated test names to hold out (default: meta.json roles, else every "
        "second test in frequency order)",
    )
    p.add_argument(
        "--holdout-fraction",
        type=share,
        metavar="SHARE",
        help="records of any machine (mast import) with no held-out test: hold out this last share of "
        "every test (default 1/3; docs/emps.md)",
    )
    p.add_argument("--workers", type=count, default=2, help="parallel processes")
    p.add_argument("--fmu", action="store_true", help="re-simulate through the SSP's (Python) FMUs")
    p.add_argument(
        "--direct",
        action="store_true",
        help="re-simulate on the direct composition of the Python models (the reference: the FMUs' own model "
        "objects, equal to 1e-12); the default when the SSP has no native variant",
    )
    p.add_argument(
        "--native",
        action="store_true",
        help="re-simulate on the SSP's native variant (build/ssp/native/, mast build --native: compiled FMUs, "
        "the Python models to 1e-9); the default when it is built (docs/diagnose.md)",
    )
    p.set_defaults(func=cmd_diagnose)

    p = sub.add_parser(
        "import", help="a lab's log (.mat or CSV) through a column map into a record folder (docs/measured-data.md)"
    )
    p.add_argument("file", help="the lab's file: .mat (MATLAB) or .csv")
    p.add_argument("--map", required=True, help="column map (TOML), e.g. examples/emps/map.toml")
    p.add_argument("--out", type=folder, required=True, help="record folder to write (meta.json and one CSV)")
    p.set_defaults(func=cmd_import)

    p = sub.add_parser(
        "replay",
        help="drive a model with a record's commands and inputs; relative error and fit "
        "per signal, plots (docs/measured-data.md)",
    )
    p.add_argument("ssp", help="the model: a built .ssp, e.g. build/ssp/EMPS_bench.ssp")
    p.add_argument(
        "--model",
        action=Renamed,
        instead="give the model's SSP as the first argument: "
        "mast replay SSP --measured DIR --out OUT (--model is "
        "diagnose's nominal parameter set)",
    )
    p.add_argument("--measured", required=True, help="record folder (mast import)")
    p.add_argument("--out", type=folder, required=True, help="folder for replay.json, replay.csv and the plots")
    p.add_argument("--set", action="append", metavar="ELEMENT.PARAMETER=VALUE", help="override a parameter")
    p.add_argument("--fmu", action="store_true", help="simulate through the FMUs (default: the direct composition)")
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser(
        "check-mechanism", help="black-box checks a mechanism FMU must pass to plug in (docs/interfaces.md)"
    )
    p.add_argument("fmu", nargs="+", help="mechanism FMU(s)")
    p.set_defaults(func=cmd_check_mechanism)

    from .analyses.compare import PAYLOAD_MISMATCH_KG

    p = sub.add_parser(
        "compare",
        help="run one sine test set on several mechanism designs or controllers: table and "
        "plots (docs/designs, docs/controller.md)",
    )
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument(
        "--mechanism",
        nargs="+",
        metavar="FMU_OR_SSP",
        help="mechanism FMUs to swap into the base system (or whole systems, .ssp/.ssd), or the name "
        "of a mechanism description without a system (3RPS): its workspace, margins and static "
        "forces beside the designs', not run",
    )
    which.add_argument(
        "--controller",
        nargs="+",
        metavar="NAME_FMU_OR_SSP",
        help="controllers: joint, workspace, feedforward, computed_torque, controller FMUs to swap into "
        "the base system, or whole systems (.ssp/.ssd)",
    )
    p.add_argument(
        "--payload",
        type=nonnegative,
        default=PAYLOAD_MISMATCH_KG,
        metavar="KG",
        help="with --controller: also run every test with this payload on the platform, unknown to the "
        f"controllers: a point mass at P, bolted to --specimen's specimen if given (default {PAYLOAD_MISMATCH_KG:g} "
        "kg; 0: no robustness runs)",
    )
    p.add_argument(
        "--out", type=folder, required=True, help="folder for comparison.csv/.json/.md, runs.csv, the plots, systems/"
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="the small test set: z motion at 1, 4 and 8 Hz (and the designs' "
        "workspaces on a coarse grid: 25 mm, 4 deg)",
    )
    p.add_argument(
        "--motions",
        nargs="+",
        choices=POSE,
        help="motions to test, coordinates of every design's mechanism (default: every coordinate of "
        "the first design's mechanism; the 3PRS's: z, psi, theta)",
    )
    p.add_argument(
        "--frequencies", nargs="+", type=hertz, metavar="HZ", help="test frequencies (default: 0.5 to 10 Hz)"
    )
    p.add_argument(
        "--set", action="append", metavar="ELEMENT.PARAMETER=VALUE", help="override a parameter in every design"
    )
    add_specimen(
        p,
        "on every run of every design or controller, unknown to the controllers (with --controller the "
        "robustness runs add --payload's point mass at P to it): " + SPECIMEN_HELP,
    )
    p.add_argument("--workers", type=count, help="parallel processes (default: the number of cores)")
    p.add_argument("--direct", action="store_true", help="run the model objects without FMI (this project's FMUs only)")
    p.add_argument("--ssd", default=str(REPO / "ssp" / "MAST.ssd"), help="base system the FMUs are swapped into")
    p.add_argument("--fmus", default=str(BUILD / "fmus"), help="FMUs of the base system's other components")
    p.set_defaults(func=cmd_compare)

    from .analyses.workspace import STEP_TILT_DEG, STEP_Z

    p = sub.add_parser(
        "workspace",
        help="the poses a design reaches within its strokes without crossing a singularity: "
        "DIR/workspace.json/.csv/.png, or one pose (docs/workspace.md)",
    )
    p.add_argument(
        "design",
        help="design name (3PRS_T, 3PRS_120, 3PRS_inclined, actuators_only), a system .ssd/.ssp, "
        "a mechanism .fmu or a mechanism description without a system (3RPS: its own strokes "
        "and home)",
    )
    p.add_argument(
        "--payload",
        type=nonnegative,
        default=0.0,
        metavar="KG",
        help="payload on the platform, centre of mass at P (static actuator forces, default 0): the point mass "
        "--specimen KG of the commands that run (docs/specimens.md)",
    )
    p.add_argument("--out", type=folder, help="folder for workspace.json, workspace.csv, workspace.png")
    p.add_argument(
        "--pose",
        metavar="Z,PSI_DEG,THETA_DEG",
        help="answer for one pose, one number per coordinate of the mechanism (m, deg; the 3PRS: z, psi, "
        "theta; a hexapod: x, y, z, psi, theta, phi, the grid then over the ones it moves from home "
        "unless --sweep): "
        "inside (exit 0) or not (exit 1), with its margins",
    )
    p.add_argument(
        "--sweep",
        metavar="C1,C2,C3",
        help="the coordinates the grid sweeps (1 to 3; default every coordinate of the mechanism), the "
        "others held at home: x,y,z the constant-orientation workspace, psi,theta,phi the orientation one",
    )
    p.add_argument(
        "--step-z",
        type=_positive("metres"),
        default=STEP_Z,
        metavar="M",
        help=f"grid step in the length coordinates (z; default {STEP_Z:g} m)",
    )
    p.add_argument(
        "--step-tilt",
        type=_positive("degrees"),
        default=STEP_TILT_DEG,
        metavar="DEG",
        help=f"grid step in the angles (psi, theta; default {STEP_TILT_DEG:g} deg)",
    )
    p.add_argument("--no-plots", action="store_true", help="write no figure")
    p.set_defaults(func=cmd_workspace)

    p = sub.add_parser(
        "animate",
        help="a run replayed in 3-D: one self-contained HTML page, play/pause, time slider, "
        "the commanded pose as a ghost (docs/animate.md)",
    )
    p.add_argument("run_dir", help="a `mast run` output folder (results.csv, summary.json)")
    from .analyses.animate import FPS, PAGE

    p.add_argument(
        "--out",
        type=animate_folder,
        metavar="DIR",
        help=f"folder for the page, DIR/{PAGE} (default: RUN_DIR)",
    )

    p.add_argument(
        "--fps",
        type=_positive("frames per second"),
        default=FPS,
        help=f"frames per second of simulated time (default {FPS:g})",
    )
    p.set_defaults(func=cmd_animate)

    p = sub.add_parser(
        "sizing",
        help="the drives of a run against their datasheet ratings: margin table, verdict, "
        "torque-speed envelope and winding temperature (docs/sizing.md)",
    )
    p.add_argument("run_dir", metavar="RUN_DIR", help="a run folder of `mast run` (results.csv, summary.json)")
    p.add_argument("--ssp", help="the system whose ratings apply (default: the one summary.json names)")
    p.add_argument(
        "--set",
        action="append",
        metavar="ELEMENT.PARAMETER=VALUE",
        help="the run's parameter overrides (default: those summary.json records)",
    )
    add_specimen(
        p,
        "the specimen the run carried, in place of the payload summary.json records (its static hold at home "
        "against the ratings goes into sizing.json): " + SPECIMEN_HELP,
    )
    p.add_argument("--out", type=folder, help="folder for sizing.json, sizing.md and the plots (default: RUN_DIR)")
    p.add_argument("--no-plots", action="store_true", help="write no figures")
    p.set_defaults(func=cmd_sizing)

    p = sub.add_parser("batch", help="run the cases of a batch config (TOML/YAML) in parallel: docs/batch.md")
    p.add_argument("config", help="batch config: .toml, .yaml or .json")
    p.add_argument(
        "--out", type=folder, required=True, help="folder for the results (manifest, per-case files, tables, plots)"
    )
    p.add_argument("--workers", type=count, help="local worker processes (default: the number of cores)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="run on this Dask scheduler (tcp://host:8786) instead")
    p.add_argument("--resume", action="store_true", help="go on with the batch in --out: skip its finished cases")
    p.add_argument("--retry-failed", action="store_true", help="with --resume: run failed and crashed cases again")
    p.add_argument("--dry-run", action="store_true", help="list the cases and stop")
    add_specimen(p, "on every case (the config's [parameters], before its cases' own): " + SPECIMEN_HELP)
    p.add_argument("--no-plots", action="store_true", help="write no figures")
    p.add_argument(
        "--max-cases",
        type=count,
        metavar="N",
        # the default lives in mast.batch (DEFAULT_MAX_CASES), too heavy to import for every command; a test
        # holds this text to it
        help="refuse a config that expands to more cases than N, counted before anything is built (default: 10000)",
    )
    p.set_defaults(func=cmd_batch)

    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, OSError, RuntimeError) as err:
        from .core.admissible import CommandError

        # the command line takes angles in degrees, so a refused pose command is stated in degrees too
        print(f"error: {err.in_degrees if isinstance(err, CommandError) else err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
