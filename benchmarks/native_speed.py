"""Native vs Python FMUs on the project's master, side by side in one process: CPU time of 10 s of the
default system at the paper's cycle times, and where the time goes (the FMUs' own time per call); the FMU
routes with the master's exchange loop compiled (the default, mast.core.exchange) and in Python.

    python benchmarks/native_speed.py [--ssp build/ssp/MAST.ssp] [--stop-time 10] [--repeats 3]
                                      [--before DIR] # also: another build's SSPs (DIR = its build/ssp)
                                      [--native-only] # only the native FMUs' route (and --before's)
                                      [--mechanisms] # also: each native mechanism FMU alone, CPU per step
                                      [--profile]  # also: instructions per FMU and call (callgrind)
                                      [--cycles]   # also: 200 instantiate/free cycles under valgrind
                                      [--hosts]    # also: our master vs libcosim and the ecos CLI, native SSP
                                      [--analyses] # also: mast reproduce and mast diagnose (paper case),
                                                   # Python vs native FMUs, wall time (about 15 min)

Needs `mast build --native`. The machine may be shared: every figure is the minimum over interleaved
repeats (the least disturbed). Also runs `benchmarks/native_cycles.c` (a C host, no Python) over each
native FMU and prints its memory figures, under valgrind with --cycles.

``--before DIR``: another build's SSPs of the same system (DIR: its ``build/ssp``, e.g. of a clone of
main built with ``make build && mast build --native``): its Python FMUs ``DIR/<ssp name>`` and native
FMUs ``DIR/native/<ssp name>``, timed interleaved with this build's in the same repeats, both printed:
the before/after figures of a change.

``--mechanisms``: every native mechanism FMU of the build (build/fmus/native: the 3PRS designs, the 3-RPS, the
hexapods) alone in fmpy, ``--mechanism-steps`` steps of 1 ms with its joints on 1 mm sines about their start
values (the home pose): CPU time per step, fmpy's Python call overhead (setReal, doStep) included, and the
real-time factor of the mechanism alone at the systems' 1 ms communication step.

``--profile``: 1 s of the native SSP under callgrind (valgrind) in a child: per FMU binary and FMI
call, the calls and the instructions they execute (inclusive: the model's code, libm, the FMI
wrapper; counted, so the same on a loaded machine).

``--hosts``: the same native SSP (MAST_standalone.ssp: the trajectory FMU drives it; a host has no
stimulus of ours), the same stop time (``--host-stop-time``, default 1.9 s: from t = 2 s on, libcosim
steps by 9.99999999997669e-05 s, which the native actuator, built for 1e-4 s, refuses; the actuator's
discretisation computed at initialisation for any step will lift that), in our master (this process: CPU time of the
process, wall time) and in libcosim and the ecos command line (child processes: their CPU time from
``getrusage(RUSAGE_CHILDREN)``, wall time around them; libcosim runs in a Python child,
``mast.hosts.cosim``, whose interpreter start and imports are measured alone and shown; the ecos CLI
runs under ``env -i``, no Python). ``--analyses``: ``mast reproduce --fmi`` on the Python and the
native SSP, and the paper case of ``mast diagnose`` (docs/diagnose.md: ``mast synthesize``
with the truth tau_c = 0.0718, J1_scale = 0.641026, seed 1) re-simulating on the direct composition
(``--direct``), the Python FMUs (``--fmu``) and the native variant (its default when built), one run
each, wall and CPU time of the child.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

from mast.core.build import default_build_dir

REPO = Path(__file__).resolve().parents[1]


def cpu_run(ssp: Path, stop: float, direct: bool = False, python_loop: bool = False) -> float:
    """CPU time of one run; ``python_loop``: the master's exchange loop in Python, not compiled (exchange.py)."""
    from mast.core.motion import SineMotion
    from mast.core.run import simulate

    os.environ["MAST_PYTHON_EXCHANGE"] = "1" if python_loop else "0"
    start = time.process_time()
    simulate(ssp, SineMotion("z", 0.01, 1.0), stop, direct=direct)
    return time.process_time() - start


PROFILED = ("fmi2SetReal", "fmi2GetReal", "fmi2DoStep")


def mechanism_step(fmu: Path, steps: int) -> float:
    """CPU time per doStep [s] of the mechanism FMU ``fmu`` alone (fmpy), its joints rho_k on 1 mm sines about
    their start values, steps of 1 ms."""
    import math

    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(fmu))
    unzip = extract(str(fmu))
    try:
        start = {v.name: float(v.start) for v in md.modelVariables if v.causality == "input"}
        joints = [n for n in start if re.fullmatch(r"rho_\d+", n)]
        refs = [next(v.valueReference for v in md.modelVariables if v.name == n) for n in joints]
        slave = FMU2Slave(
            guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench"
        )
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        begin = time.process_time()
        for k in range(steps):
            t = k * 1e-3
            slave.setReal(refs, [start[n] + 1e-3 * math.sin(2.0 * math.pi * t + i) for i, n in enumerate(joints)])
            slave.doStep(t, 1e-3)
        cpu = time.process_time() - begin
        slave.terminate()
        slave.freeInstance()
    finally:
        shutil.rmtree(unzip, ignore_errors=True)
    return cpu / steps


def call_costs(callgrind_out: Path) -> dict[tuple[str, str], list[int]]:
    """From a callgrind output file: (object, function) -> [calls, inclusive instructions], summed over every
    call arc into it (the format's ``calls=`` lines, the cost line after each being the call's inclusive cost),
    for the functions PROFILED."""
    names: dict[str, dict[str, str]] = {"ob": {}, "fn": {}}
    current = {"ob": "", "cob": None, "cfn": None}
    out: dict[tuple[str, str], list[int]] = {}
    pending = None

    def name(kind: str, text: str) -> str:  # "(id) name" defines an id, "(id)" reuses it (compressed strings)
        m = re.match(r"\((\d+)\)\s*(.*)", text)
        if not m:
            return text
        if m.group(2):
            names[kind][m.group(1)] = m.group(2)
        return names[kind].get(m.group(1), text)

    with open(callgrind_out) as f:
        for line in f:
            if pending is not None:
                key, calls = pending
                pending = None
                fields = line.split()
                if len(fields) >= 2:
                    row = out.setdefault(key, [0, 0])
                    row[0] += calls
                    row[1] += int(fields[1])
                continue
            if line.startswith("ob="):
                current["ob"] = name("ob", line[3:].strip())
            elif line.startswith("cob="):
                current["cob"] = name("ob", line[4:].strip())
            elif line.startswith("cfn="):
                current["cfn"] = name("fn", line[4:].strip())
            elif line.startswith("fn="):
                name("fn", line[3:].strip())
            elif line.startswith("calls="):
                fn, ob = current["cfn"], current["cob"] or current["ob"]
                current["cob"] = current["cfn"] = None
                pending = ((ob, fn), int(line[6:].split()[0]))
    return {key: row for key, row in out.items() if key[1] in PROFILED}


def profile(ssp: Path, stop: float) -> None:
    """Where the native run's work goes, per component and FMI call: instructions counted by callgrind
    (deterministic: a loaded machine does not change them) in a child simulating ``stop`` s of ``ssp``."""
    if not shutil.which("valgrind"):
        print("  --profile: valgrind is not on PATH")
        return
    with tempfile.TemporaryDirectory(prefix="mast_profile_") as tmp:
        out = Path(tmp) / "callgrind.out"
        code = (
            f"from mast.core.motion import SineMotion\nfrom mast.core.run import simulate\n"
            f"simulate({str(ssp)!r}, SineMotion('z', 0.01, 1.0), {stop!r})\n"
        )
        subprocess.run(
            ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", sys.executable, "-c", code],
            check=True,
            capture_output=True,
            env={**os.environ, "MAST_PYTHON_EXCHANGE": "0"},
        )
        costs = call_costs(out)
    print(f"{ssp.name} (native FMUs), {stop:g} s simulated under callgrind: instructions per call, by FMU binary")
    print(f"  {'binary':22s} {'call':12s} {'calls':>8s} {'instr/call':>11s} {'instr in all':>13s}")
    for (obj, fn), (calls, cost) in sorted(costs.items(), key=lambda kv: -kv[1][1]):
        print(f"  {Path(obj).name:22s} {fn:12s} {calls:8d} {cost / max(calls, 1):11.0f} {cost:13d}")
    print(f"  FMI calls, all: {sum(cost for calls, cost in costs.values())} instructions")


def _child_cpu() -> float:
    import resource

    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed_child(command: list[str], **kwargs) -> tuple[float, float]:
    """(CPU, wall) seconds of a child process; CalledProcessError with its output if it fails."""
    cpu, wall = _child_cpu(), time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, **kwargs)
    wall, cpu = time.perf_counter() - wall, _child_cpu() - cpu
    if done.returncode not in (0, 3):  # mast diagnose: 3 = an unexplained residual, still a run
        raise subprocess.CalledProcessError(done.returncode, command, done.stdout, done.stderr)
    return cpu, wall


def hosts(native: Path, stop: float, repeats: int) -> None:
    """Our master vs libcosim and the ecos CLI on the same native SSP (module docstring)."""
    from mast.core.run import simulate
    from mast.hosts.cosim import COMPARED, availability, run_host

    signals = list(COMPARED)
    best = {"our master": (float("inf"), float("inf"))}
    for _ in range(repeats):
        cpu, wall = time.process_time(), time.perf_counter()
        simulate(native, None, stop, record=signals)
        row = (time.process_time() - cpu, time.perf_counter() - wall)
        best["our master"] = min(best["our master"], row)
        for host, kwargs in (("libcosim", {}), ("ecos", {"python_free": True})):
            if availability(host):
                continue
            cpu, wall = _child_cpu(), time.perf_counter()
            run_host(host, native, stop, signals, timeout=3600, **kwargs)
            row = (_child_cpu() - cpu, time.perf_counter() - wall)
            best[host] = min(best.get(host, (float("inf"),) * 2), row)
    start = min(timed_child([sys.executable, "-c", "import mast.hosts.cosim, libcosimpy"]) for _ in range(repeats))
    print(
        f"{native.name} (native FMUs), {stop:g} s simulated, the SSP's own trajectory, {len(signals)} signals "
        f"recorded, best of {repeats}:"
    )
    ours = best["our master"]
    for label, (cpu, wall) in best.items():
        ratio = (
            ""
            if label == "our master"
            else (
                f"   {label}/ours CPU {cpu / ours[0]:.2f}, ours/{label} {ours[0] / cpu:.2f}; wall "
                f"{wall / ours[1]:.2f}, "
                f"{ours[1] / wall:.2f}"
            )
        )
        print(f"  {label:12s} {cpu:7.2f} s CPU {wall:7.2f} s wall   real-time factor (CPU) {stop / cpu:6.2f}{ratio}")
    for host in ("libcosim", "ecos"):
        if host not in best:
            print(f"  {host}: not run ({availability(host)})")
    print(
        f"  (of libcosim's: its Python child starting and importing libcosimpy alone: {start[0]:.2f} s CPU, "
        f"{start[1]:.2f} s wall)"
    )


def analyses(python: Path, native: Path, workers: int) -> None:
    """``mast reproduce`` and the paper case of ``mast diagnose``, Python vs native FMUs (module docstring)."""
    mast = [sys.executable, "-m", "mast.cli"]
    with tempfile.TemporaryDirectory(prefix="mast_bench_") as tmp:
        tmp = Path(tmp)
        measured = tmp / "paper_case"
        timed_child(
            [
                *mast,
                "synthesize",
                str(python),
                "--out",
                str(measured),
                "--set",
                "actuator.tau_c=0.0718",
                "--set",
                "actuator.J1_scale=0.641026",
                "--seed",
                "1",
            ]
        )
        rows = []
        for label, ssp in (("Python FMUs", python), ("native FMUs", native)):
            rows.append(
                (
                    f"mast reproduce --fmi, {label}",
                    timed_child(
                        [
                            *mast,
                            "reproduce",
                            str(ssp),
                            "--fmi",
                            "--workers",
                            str(workers),
                            "--out",
                            str(tmp / f"reproduce_{label[:6]}"),
                        ]
                    ),
                )
            )
        for label, ssp, flag in (
            ("direct composition", python, ["--direct"]),
            ("Python FMUs", python, ["--fmu"]),
            ("native FMUs (the default when built)", python, []),
        ):
            rows.append(
                (
                    f"mast diagnose (paper case), {label}",
                    timed_child(
                        [
                            *mast,
                            "diagnose",
                            str(ssp),
                            "--measured",
                            str(measured),
                            "--workers",
                            str(workers),
                            "--out",
                            str(tmp / f"diagnose_{len(rows)}"),
                            *flag,
                        ]
                    ),
                )
            )
        print(f"analyses, {workers} workers, one run each (child CPU time of every process, wall time):")
        for label, (cpu, wall) in rows:
            print(f"  {label:48s} {wall:7.1f} s wall {cpu:7.1f} s CPU")


def cycles(fmu: Path, step: float, valgrind: bool) -> str:
    from lxml import etree

    from mast.core.native.compiler import compiler, fmi_headers

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        host = tmp / "cycles"
        subprocess.run(
            [
                compiler(),
                "-O2",
                f"-I{fmi_headers()}",
                "-o",
                str(host),
                str(REPO / "benchmarks" / "native_cycles.c"),
                "-ldl",
            ],
            check=True,
        )
        with zipfile.ZipFile(fmu) as z:
            z.extractall(tmp / "fmu")
        guid = etree.parse(str(tmp / "fmu" / "modelDescription.xml")).getroot().get("guid")
        library = tmp / "fmu" / "binaries" / "linux64" / f"{fmu.stem}.so"
        args = [str(host), str(library), guid, "200", repr(step)]
        plain = subprocess.run([*args[:3], "5000", args[4]], capture_output=True, text=True)
        rss10, rss5000, ok, _ = plain.stdout.split()
        text = f"{fmu.stem:20s} 5000 cycles: RSS {rss10} -> {rss5000} KiB, statuses as expected: {ok == '1'}"
        if valgrind and shutil.which("valgrind"):
            checked = subprocess.run(
                [
                    "valgrind",
                    "-q",
                    "--error-exitcode=3",
                    "--leak-check=full",
                    "--errors-for-leak-kinds=definite",
                    *args,
                ],
                capture_output=True,
                text=True,
            )
            text += f"; valgrind, 200 cycles: {'clean' if checked.returncode == 0 else checked.stderr[-800:]}"
        return text


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ssp", default=str(default_build_dir() / "ssp" / "MAST.ssp"))
    parser.add_argument("--stop-time", type=float, default=10.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--before",
        metavar="DIR",
        help="also time another build's SSPs: DIR/<ssp name> (Python FMUs) and DIR/native/<ssp name> (native FMUs)",
    )
    parser.add_argument(
        "--native-only", action="store_true", help="time the native FMUs alone (and --before's): a short run"
    )
    parser.add_argument("--mechanisms", action="store_true", help="also: each native mechanism FMU alone")
    parser.add_argument("--mechanism-steps", type=int, default=10000, help="steps of 1 ms of --mechanisms")
    parser.add_argument("--profile", action="store_true", help="also: the native run's instructions per FMU and call")
    parser.add_argument("--cycles", action="store_true", help="also run the C host's cycles under valgrind")
    parser.add_argument("--hosts", action="store_true", help="also run the native SSP in libcosim and the ecos CLI")
    parser.add_argument("--host-stop-time", type=float, default=1.9, help="stop time of the --hosts runs [s]")
    parser.add_argument("--analyses", action="store_true", help="also time mast reproduce and mast diagnose")
    parser.add_argument("--workers", type=int, default=2, help="workers of mast reproduce and diagnose")
    args = parser.parse_args()
    python = Path(args.ssp)
    native = python.parent / "native" / python.name
    if not native.exists():
        print(f"{native} is missing: run `mast build --native` first", file=sys.stderr)
        return 2
    stop = args.stop_time
    rows = {
        "direct composition (Python models)": (python, True, True),
        "Python FMUs, exchange loop in Python": (python, False, True),
        "Python FMUs": (python, False, False),
        "native FMUs, exchange loop in Python": (native, False, True),
        "native FMUs": (native, False, False),
    }
    before = (
        {"Python FMUs": Path(args.before) / python.name, "native FMUs": Path(args.before) / "native" / python.name}
        if args.before
        else {}
    )
    missing = [str(p) for p in before.values() if not p.exists()]
    if missing:
        print(f"{', '.join(missing)} missing (--before: another build's build/ssp folder)", file=sys.stderr)
        return 2
    if args.native_only:
        rows = {"native FMUs": rows["native FMUs"]}
        before = {k: v for k, v in before.items() if k == "native FMUs"}
    rows.update({f"{route}, before (--before)": (ssp, False, False) for route, ssp in before.items()})
    best = {label: float("inf") for label in rows}
    for _ in range(args.repeats):
        for label, (ssp, direct, python_loop) in rows.items():
            best[label] = min(best[label], cpu_run(ssp, stop, direct, python_loop))
    print(
        f"{python.name}: {stop:g} s simulated, z sine 10 mm at 1 Hz, CPU time of this process, best of {args.repeats}"
    )
    for label, cpu in best.items():
        print(f"  {label:36s} {cpu:7.2f} s CPU   real-time factor {stop / cpu:7.2f}")
    if not args.native_only:
        print(f"  Python FMUs / native FMUs CPU time: {best['Python FMUs'] / best['native FMUs']:.1f}")
        print(
            f"  native co-simulation / direct composition: "
            f"{best['native FMUs'] / best['direct composition (Python models)']:.2f}"
        )
        print(
            f"  compiled / Python exchange loop CPU time: Python FMUs "
            f"{best['Python FMUs'] / best['Python FMUs, exchange loop in Python']:.2f}, native FMUs "
            f"{best['native FMUs'] / best['native FMUs, exchange loop in Python']:.2f}"
        )
    for route in before:
        print(
            f"  {route} after / before ({args.before}) CPU time: "
            f"{best[route] / best[f'{route}, before (--before)']:.2f}"
        )
    if args.mechanisms:
        from mast.core.build import FMUS

        print(f"native mechanism FMUs alone (fmpy), {args.mechanism_steps} steps of 1 ms, best of {args.repeats}")
        for spec in FMUS:
            fmu = default_build_dir() / "fmus" / "native" / f"{spec.model_identifier}.fmu"
            if spec.package == "mechanism" and fmu.exists():
                cpu = min(mechanism_step(fmu, args.mechanism_steps) for _ in range(args.repeats))
                name = spec.model_identifier
                print(f"  {name:18s} {cpu * 1e6:7.1f} us CPU per step   real-time factor {1e-3 / cpu:8.1f}")
    if args.profile:
        for ssp in [native] + ([before["native FMUs"]] if before else []):
            profile(ssp, 1.0)
    if args.hosts:
        hosts(native.parent / "MAST_standalone.ssp", args.host_stop_time, args.repeats)
    if args.analyses:
        analyses(python, native, args.workers)
    for ident, step in (
        ("MastActuator", 1e-4),
        ("MastMechanism", 1e-3),
        ("MastController", 1e-4),
        ("MastTrajectory", 1e-4),
    ):
        fmu = default_build_dir() / "fmus" / "native" / f"{ident}.fmu"
        if fmu.exists():
            print("  " + cycles(fmu, step, args.cycles))
    return 0


if __name__ == "__main__":
    sys.exit(main())
