"""Native vs Python FMUs on the project's master, side by side in one process: CPU time of 10 s of the
default system at the paper's cycle times, and where the time goes (the FMUs' own time per call); the FMU
routes with the master's exchange loop compiled (the default, mast.core.exchange) and in Python.

    python benchmarks/native_speed.py [--ssp build/ssp/MAST.ssp] [--stop-time 10] [--repeats 3]
                                      [--cycles]   # also: 200 instantiate/free cycles under valgrind

Needs `mast build --native`. The machine may be shared: every figure is the minimum over interleaved
repeats (the least disturbed). Also runs `benchmarks/native_cycles.c` (a C host, no Python) over each
native FMU and prints its memory figures, under valgrind with --cycles.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def cpu_run(ssp: Path, stop: float, direct: bool = False, python_loop: bool = False) -> float:
    """CPU time of one run; ``python_loop``: the master's exchange loop in Python, not compiled (exchange.py)."""
    from mast.core.motion import SineMotion
    from mast.core.run import simulate

    os.environ["MAST_PYTHON_EXCHANGE"] = "1" if python_loop else "0"
    start = time.process_time()
    simulate(ssp, SineMotion("z", 0.01, 1.0), stop, direct=direct)
    return time.process_time() - start


def cycles(fmu: Path, step: float, valgrind: bool) -> str:
    from lxml import etree

    from mast.core.native.build import compiler, fmi_headers

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        host = tmp / "cycles"
        subprocess.run([compiler(), "-O2", f"-I{fmi_headers()}", "-o", str(host),
                        str(REPO / "benchmarks" / "native_cycles.c"), "-ldl"], check=True)
        with zipfile.ZipFile(fmu) as z:
            z.extractall(tmp / "fmu")
        guid = etree.parse(str(tmp / "fmu" / "modelDescription.xml")).getroot().get("guid")
        library = tmp / "fmu" / "binaries" / "linux64" / f"{fmu.stem}.so"
        args = [str(host), str(library), guid, "200", repr(step)]
        plain = subprocess.run([*args[:3], "5000", args[4]], capture_output=True, text=True)
        rss10, rss5000, ok, _ = plain.stdout.split()
        text = f"{fmu.stem:20s} 5000 cycles: RSS {rss10} -> {rss5000} KiB, statuses as expected: {ok == '1'}"
        if valgrind and shutil.which("valgrind"):
            checked = subprocess.run(["valgrind", "-q", "--error-exitcode=3", "--leak-check=full",
                                      "--errors-for-leak-kinds=definite", *args], capture_output=True, text=True)
            text += f"; valgrind, 200 cycles: {'clean' if checked.returncode == 0 else checked.stderr[-800:]}"
        return text


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ssp", default=str(REPO / "build" / "ssp" / "MAST.ssp"))
    parser.add_argument("--stop-time", type=float, default=10.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--cycles", action="store_true", help="also run the C host's cycles under valgrind")
    args = parser.parse_args()
    python = Path(args.ssp)
    native = python.parent / "native" / python.name
    if not native.exists():
        print(f"{native} is missing: run `mast build --native` first", file=sys.stderr)
        return 2
    stop = args.stop_time
    rows = {"direct composition (Python models)": (python, True, True),
            "Python FMUs, exchange loop in Python": (python, False, True), "Python FMUs": (python, False, False),
            "native FMUs, exchange loop in Python": (native, False, True), "native FMUs": (native, False, False)}
    best = {label: float("inf") for label in rows}
    for _ in range(args.repeats):
        for label, (ssp, direct, python_loop) in rows.items():
            best[label] = min(best[label], cpu_run(ssp, stop, direct, python_loop))
    print(f"{python.name}: {stop:g} s simulated, z sine 10 mm at 1 Hz, CPU time of this process, "
          f"best of {args.repeats}")
    for label, cpu in best.items():
        print(f"  {label:36s} {cpu:7.2f} s CPU   real-time factor {stop / cpu:7.2f}")
    print(f"  Python FMUs / native FMUs CPU time: {best['Python FMUs'] / best['native FMUs']:.1f}")
    print(f"  native co-simulation / direct composition: "
          f"{best['native FMUs'] / best['direct composition (Python models)']:.2f}")
    print(f"  compiled / Python exchange loop CPU time: Python FMUs "
          f"{best['Python FMUs'] / best['Python FMUs, exchange loop in Python']:.2f}, native FMUs "
          f"{best['native FMUs'] / best['native FMUs, exchange loop in Python']:.2f}")
    for ident, step in (("MastActuator", 1e-4), ("MastMechanism", 1e-3), ("MastController", 1e-4),
                        ("MastTrajectory", 1e-4)):
        fmu = REPO / "build" / "fmus" / "native" / f"{ident}.fmu"
        if fmu.exists():
            print("  " + cycles(fmu, step, args.cycles))
    return 0


if __name__ == "__main__":
    sys.exit(main())
