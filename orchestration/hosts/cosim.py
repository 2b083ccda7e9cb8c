"""Run a built SSP in third-party co-simulation hosts, to check the FMUs work where we did not write the master.

Hosts (all from PyPI, see the ``test`` extra of pyproject.toml):

- ``libcosim``: the Open Simulation Platform's libcosim (C++) through libcosimpy;
- ``ecospy``: ecos (C++) through its Python binding;
- ``ecos``: ecos's command-line tool, a C++ program: no Python around the FMUs
  unless the host loads one, hence ``LD_PRELOAD=libpython3.X.so``.

Each run happens in a child process: a host that crashes cannot take the caller
with it, and the environment the C++ libraries need (``LD_LIBRARY_PATH`` for
libtbb, ``LD_PRELOAD`` for libpython) is set before they load. The SSP is used
as built (``mast build``: parameter bindings flattened to one set per component,
named ``default``, which ecos is told to apply); step sizes come from its
``osp:`` annotations (libcosim reads the base step, ecos gets it from us).

The MAST systems step every component at the same step (T_cur = 100 us) and no FMU declares direct
feedthrough, so every host that follows FMI 2.0's calling sequence computes what the project's master
computes (``RELATIVE``; docs/using-the-fmus.md). What the hosts do differently would show in another
system: both iterate a fixed number of passes (one per component) to initialise, where our master
iterates to convergence; ecos passes the outputs of a component stepped slower than the base step on at
the next base step, where libcosim and our master pass them on at the end of that component's own step.

Command line (used by ``run_host``; also handy by hand)::

    python -m mast.hosts.cosim libcosim build/ssp/MAST_standalone.ssp --stop-time 1 --signal mechanism.z --out z.csv

By hand: ``mast hosts --show ecos`` prints the environment and the ecos command line
``run_host`` uses (with a CSV configuration: without one, ecos writes every variable of every
component at every base step, which costs more than the simulation); from Python,
``import_ecospy()`` loads ecospy without ``LD_LIBRARY_PATH``.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import importlib.util
import os
import shutil
import stat
import subprocess
import sys
import sysconfig
import tempfile
import zipfile
from pathlib import Path
from typing import Mapping, Optional, Sequence, Union

import numpy as np

from fmus.mechanism.topology import POSE

from ..core import ssd
from ..core.build import FLAT_SET_NAME  # the one parameter set per component of a built SSP: ecos applies it by name
from ..core.master import Result
from ..core.ssp import SSPArchive

HOSTS = ("libcosim", "ecospy", "ecos")


class HostError(RuntimeError):
    """The host failed to load or run the SSP; the message carries the end of its output."""


class HostUnavailable(HostError):
    """The host cannot run here; the message says precisely why."""


# -- what each host needs ---------------------------------------------------------------
def _libpython() -> Path:
    """The shared libpython a C/C++ host must preload for pythonfmu FMUs."""
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        raise HostUnavailable(
            f"{sys.executable} is a Python built without --enable-shared: there is no libpython "
            "for a C/C++ host to preload, so pythonfmu FMUs cannot run in one"
        )
    libdir = Path(sysconfig.get_config_var("LIBDIR") or "")
    for name in (sysconfig.get_config_var("INSTSONAME"), sysconfig.get_config_var("LDLIBRARY")):
        if name and (libdir / name).exists():
            return libdir / name
    raise HostUnavailable(f"no shared libpython in {libdir} (INSTSONAME={sysconfig.get_config_var('INSTSONAME')})")


def _tbb_dir() -> Path:
    """Folder of libtbb.so.12 from the ``tbb`` wheel (ecos links it; the wheel puts it in <prefix>/lib)."""
    try:
        files = importlib.metadata.distribution("tbb").files or []
    except importlib.metadata.PackageNotFoundError:
        raise HostUnavailable("ecos needs libtbb.so.12: `pip install tbb` (in the project's test extra)") from None
    for file in files:
        if file.name.startswith("libtbb.so.12"):
            return Path(file.locate()).resolve().parent
    raise HostUnavailable("the installed tbb package has no libtbb.so.12")


def _package_dir(name: str, pip_name: str) -> Path:
    spec = importlib.util.find_spec(name)  # does not import it (ecospy loads libecosc.so on import)
    if spec is None or not spec.submodule_search_locations:
        raise HostUnavailable(f"{name} is not installed: `pip install {pip_name}` (in the project's test extra)")
    return Path(list(spec.submodule_search_locations)[0])


def _ecos_binary(workdir: Path) -> Path:
    """ecospy ships the ecos CLI in ecospy/binaries/ without the executable bit: use a copy that has it."""
    source = _package_dir("ecospy", "ecospy") / "binaries" / "ecos"
    if not source.exists():
        raise HostUnavailable(f"{source} is missing: this ecospy wheel has no Linux ecos command-line tool")
    target = workdir / "ecos"
    shutil.copy2(source, target)
    target.chmod(target.stat().st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
    return target


def availability(host: str) -> Optional[str]:
    """None if ``host`` can run here, else the reason it cannot."""
    if host not in HOSTS:
        return f"unknown host '{host}'; hosts: {', '.join(HOSTS)}"
    if not sys.platform.startswith("linux"):
        return f"the host runners are written for Linux (LD_LIBRARY_PATH, LD_PRELOAD); this is {sys.platform}"
    try:
        if host == "libcosim":
            _package_dir("libcosimpy", "libcosimpy")
        else:
            _package_dir("ecospy", "ecospy")
            _tbb_dir()
            if host == "ecos":
                _libpython()
                if not (_package_dir("ecospy", "ecospy") / "binaries" / "ecos").exists():
                    return "this ecospy wheel has no Linux ecos command-line tool (ecospy/binaries/ecos)"
    except HostUnavailable as err:
        return str(err)
    return None


def _environment(host: str) -> dict[str, str]:
    return {**os.environ, **host_environment(host)}


def host_environment(host: str) -> dict[str, str]:
    """The variables ``host`` needs on top of this process's environment (each keeps what it held)."""
    env: dict[str, str] = {}
    if host in ("ecospy", "ecos"):
        env["LD_LIBRARY_PATH"] = os.pathsep.join(p for p in (str(_tbb_dir()), os.environ.get("LD_LIBRARY_PATH")) if p)
    if host == "ecos":
        # the C++ host starts its own interpreter inside the FMU's library: give it this Python's
        # standard library and the packages of this environment (numpy, scipy for the models)
        env["LD_PRELOAD"] = " ".join(p for p in (str(_libpython()), os.environ.get("LD_PRELOAD")) if p)
        env["PYTHONHOME"] = sys.base_prefix
        paths = dict.fromkeys([sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]])
        previous = os.environ.get("PYTHONPATH")
        env["PYTHONPATH"] = os.pathsep.join([*paths, *([previous] if previous else [])])
    return env


def import_ecospy():
    """``import ecospy`` in this process, without ``LD_LIBRARY_PATH``: libtbb.so.12 (from the ``tbb``
    wheel, in <venv>/lib, which the loader does not search) is loaded first, globally."""
    import ctypes

    ctypes.CDLL(str(_tbb_dir() / "libtbb.so.12"), mode=ctypes.RTLD_GLOBAL)
    import ecospy

    return ecospy


def ecos_command(
    ssp: Path,
    stop_time: float,
    signals: Sequence[str],
    sample_step: float,
    workdir: Path,
    base_step: Optional[float] = None,
    fmu_log: bool = False,
    executable: str = "ecos",
) -> list[str]:
    """The ecos command line for ``ssp`` (its CSV configuration written to ``workdir/csv.xml``).

    The options that matter: ``--parameterSet default`` (ecos applies bindings only by name),
    a stop time half a step past the end (ecos truncates stop/step), and ``--csvConfig`` naming
    the ``signals`` and a decimation to ``sample_step``: without it, ecos writes every variable of
    every component at every base step (measured: 0.2 s simulated took 14 s).
    """
    base_step = base_step or _base_step(ssp)
    _write_ecos_csv_config(workdir / "csv.xml", signals, _decimation(sample_step, base_step))
    command = [
        executable,
        "simulate",
        "--path",
        str(ssp),
        "--stepSize",
        repr(base_step),
        "--stopTime",
        repr(stop_time + 0.5 * base_step),  # ecos truncates stop/step
        "--parameterSet",
        FLAT_SET_NAME,
        "--csvConfig",
        str(workdir / "csv.xml"),
    ]
    return command + (["--debugLogging", "--logLevel", "debug"] if fmu_log else ["--logLevel", "warn"])


def show(host: str, ssp: Union[str, Path], stop_time: float, signals: Sequence[str], workdir: Path) -> str:
    """What to type to run ``host`` by hand: the environment (shell ``export`` lines) and, for the ecos
    command line, the command (its CSV configuration written into ``workdir``)."""
    import shlex

    reason = availability(host)
    if reason:
        raise HostUnavailable(f"{host}: {reason}")
    lines = [f"export {name}={shlex.quote(value)}" for name, value in host_environment(host).items()]
    if host == "ecos":
        binary = _package_dir("ecospy", "ecospy") / "binaries" / "ecos"
        lines.append(f"# ecos ships without the executable bit: cp {binary} . && chmod +x ecos")
        lines.append(
            shlex.join(ecos_command(Path(ssp).resolve(), stop_time, signals, 1e-3, workdir, executable="./ecos"))
        )
    elif host == "ecospy":
        lines.append("# then `import ecospy` works; or, without the export, from mast.hosts.cosim import import_ecospy")
    return "\n".join(lines)


# -- running ----------------------------------------------------------------------------
def run_host(
    host: str,
    ssp: Union[str, Path],
    stop_time: float,
    signals: Sequence[str],
    sample_step: float = 1e-3,
    timeout: float = 600.0,
    fmu_log: bool = False,
    base_step: Optional[float] = None,
    python_free: bool = False,
    worker_threads: Optional[int] = None,
    wrapper: Sequence[str] = (),
) -> Result:
    """Run the built ``ssp`` in ``host`` until ``stop_time`` and return ``signals`` every ``sample_step``.

    ``signals`` are ``element.connector`` names (parameters too). Raises
    HostUnavailable when the host cannot run here, HostError when it fails
    (the message ends with what the host printed). A host killed by a signal
    after the run had finished and its results were written is reported in
    ``result.stats["exit_signal"]``, not raised: pythonfmu's teardown at process
    exit can do that to a C/C++ host (docs/using-the-fmus.md). What the host printed is in
    ``result.stats["log"]``; ``fmu_log=True`` makes the ecos CLI print the FMUs'
    messages too (it logs them at debug level only). libcosim prints them from
    warning level on, always. The ecos CLI also runs a single .fmu (its one
    component is named ``instance``); give it ``base_step`` then. ``python_free=True`` (ecos
    only, for native FMUs: ``mast build --native``) runs the ecos CLI under ``env -i`` with
    nothing but its own libraries' path: no Python on PATH, no LD_PRELOAD, PYTHONHOME, PYTHONPATH.
    ``worker_threads`` (libcosim only): the threads libcosim steps the FMUs in (default: its own choice, the
    machine's hardware threads less one), set through ``hardware_concurrency.c``; ``result.stats["threads"]``
    is the number of threads the child process had at the end of the run.
    ``wrapper`` (ecos only): a command the ecos CLI runs under, e.g. ``("valgrind", "--error-exitcode=99")``.
    """
    if wrapper and host != "ecos":
        raise ValueError(f"{host}: only the ecos command line runs under a wrapper command")
    if python_free and host != "ecos":
        raise ValueError(f"{host}: only the ecos command line runs without Python (python_free=True)")
    if worker_threads is not None and (host != "libcosim" or worker_threads < 1):
        raise ValueError(f"{host}: worker_threads={worker_threads!r}: libcosim only, and a whole number >= 1")
    reason = availability(host)
    if reason:
        raise HostUnavailable(f"{host}: {reason}")
    ssp = Path(ssp).resolve()
    with tempfile.TemporaryDirectory(prefix=f"mast_{host}_") as tmp:
        work = Path(tmp)
        out = work / "result.csv"
        if host == "ecos":
            command = ecos_command(
                ssp, stop_time, signals, sample_step, work, base_step, fmu_log, str(_ecos_binary(work))
            )
            command = [*wrapper, *command]
            if python_free:
                command = ["env", "-i", f"LD_LIBRARY_PATH={_tbb_dir()}", *command]
        else:
            command = [
                sys.executable,
                "-m",
                "mast.hosts.cosim",
                host,
                str(ssp),
                "--stop-time",
                repr(stop_time),
                "--sample-step",
                repr(sample_step),
                "--out",
                str(out),
            ]
            for s in signals:
                command += ["--signal", s]
        env = _environment(host)
        if worker_threads is not None:
            env["LD_PRELOAD"] = " ".join(p for p in (str(_concurrency_library()), env.get("LD_PRELOAD")) if p)
            env["MAST_HARDWARE_CONCURRENCY"] = str(worker_threads + 1)
        env["TMPDIR"] = str(work / "tmp")  # ecos leaves its extracted SSP behind: in a folder removed here
        (work / "tmp").mkdir()
        try:
            proc = subprocess.run(command, cwd=work, env=env, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            raise HostError(f"{host}: no result after {timeout:g} s") from None
        log = proc.stdout + proc.stderr
        if host == "ecos":
            out = work / f"{ssp.stem}.csv"
        result = None
        if proc.returncode <= 0 and out.exists():  # our child writes its CSV as its last act
            try:
                result = _read_ecos_csv(out, signals) if host == "ecos" else Result.read_csv(out)
            except ValueError:  # a line cut short: the host died while writing
                result = None
        if (
            result is None
            or proc.returncode > 0
            or not len(result.time)
            or result.time[-1] < stop_time - 0.5 * sample_step
        ):  # ecos writes its CSV as it goes
            raise HostError(f"{host} failed on {ssp.name} ({_describe(proc.returncode)}):\n{_tail(log)}")
        result.stats["log"] = log
        threads = [line.split()[-1] for line in log.splitlines() if line.startswith(THREADS_LINE)]
        if threads:
            result.stats["threads"] = int(threads[-1])
        if proc.returncode < 0:  # killed after the run: pythonfmu's teardown in a C/C++ host (docs/using-the-fmus.md)
            result.stats["exit_signal"] = _describe(proc.returncode)
        return result


#: what the libcosim child prints after its run: the number of threads of its process
THREADS_LINE = "libcosim child threads:"


def _concurrency_library() -> Path:
    """hardware_concurrency.c compiled (once per machine and source, into the exchange loop's cache folder)."""
    import hashlib

    from ..core.exchange import cache_dir
    from ..core.native.compiler import NativeBuildError, compiler

    source = Path(__file__).with_name("hardware_concurrency.c")
    target = cache_dir() / f"hardware_concurrency_{hashlib.sha256(source.read_bytes()).hexdigest()[:16]}.so"
    if not target.exists():
        target.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix="mast_concurrency_", dir=target.parent) as tmp:
            built = Path(tmp) / target.name
            done = subprocess.run(
                [compiler(), "-O2", "-shared", "-fPIC", "-o", str(built), str(source)], capture_output=True, text=True
            )
            if done.returncode != 0:
                raise NativeBuildError(f"{source.name}: the C compiler failed:\n{done.stderr[-2000:]}")
            os.replace(built, target)  # whole or absent for a concurrent process
    return target


def _describe(code: int) -> str:
    if code < 0:
        import signal

        return f"killed by {signal.Signals(-code).name}"
    return f"exit status {code}"


def _tail(text: str, lines: int = 40) -> str:
    return "\n".join(text.strip().splitlines()[-lines:])


def _base_step(ssp: Path) -> float:
    with SSPArchive(ssp) as archive:
        if not archive.system.base_step:
            raise HostError(f"{ssp}: no osp:FixedStepAlgorithm baseStepSize: the base step is unknown")
        return archive.system.base_step


def _decimation(sample_step: float, base_step: float) -> int:
    m = round(sample_step / base_step)
    if m < 1 or abs(m * base_step - sample_step) > 1e-9 * sample_step:
        raise ValueError(f"sample step {sample_step:g} s is not a whole multiple of the base step {base_step:g} s")
    return m


def write_csv(result: Result, path: Path) -> None:
    """time and the signals, every double written exactly (17 significant digits)."""
    names = list(result.signals)
    table = np.column_stack([result.time] + [result.signals[n] for n in names])
    np.savetxt(path, table, delimiter=",", header=",".join(["time"] + names), comments="", fmt="%.17g")


# -- agreement with the project's master ------------------------------------------------------
#: signals compared between a host and the project's master for the 3PRS (MAST_standalone.ssp), with their unit:
#: ``compared_signals`` of that system; other systems' come from their own SSD
COMPARED = {
    "mechanism.z": "m",
    "mechanism.psi": "rad",
    "mechanism.theta": "rad",
    **{f"actuator_{k}.rho": "m" for k in (1, 2, 3)},
    **{f"actuator_{k}.i_m": "A" for k in (1, 2, 3)},
    **{f"mechanism.F_{k}": "N" for k in (1, 2, 3)},
}
#: a host that follows FMI 2.0's calling sequence at the SSD's step sizes computes what our master computes: every
#: signal agrees to RELATIVE of its largest magnitude over the run (+ ABSOLUTE, for a signal that stays at rounding
#: level, such as x and y in a z motion). The last bits differ: each host adds its steps to the time it passes to
#: doStep in its own way. The ecos command line prints 6 decimals: it agrees with ecospy to half a unit of the last.
RELATIVE = 1e-9
ABSOLUTE = 1e-12
#: the drives' force rates (docs/coupling.md), left out of the comparisons: between hosts they differ by up to a
#: tenth of their peak where every other signal, Fc and Mc among them, agrees to RELATIVE (not understood yet)
RATES = ("F_drive_dot", "F_drive_ddot")


def comparable(signals: Sequence[str]) -> list[str]:
    """``signals`` without the drives' force rates (``RATES``)."""
    return [s for s in signals if s.rsplit(".", 1)[-1] not in RATES]


PRINTED = 5.0001e-7


def out_of_agreement(deviation: Mapping[str, float], reference: Result, absolute: float = ABSOLUTE) -> list[str]:
    """The signals whose ``deviations`` from ``reference`` (our master) exceed RELATIVE of their largest magnitude
    over the run + ``absolute``."""
    return [s for s, d in deviation.items() if not d <= RELATIVE * float(np.max(np.abs(reference[s]))) + absolute]


def agreement_used(deviation: Mapping[str, float], reference: Result, absolute: float = ABSOLUTE) -> float:
    """The largest ratio of a signal's deviation to its agreement (``out_of_agreement``): at most 1 when it holds."""
    return max(d / (RELATIVE * float(np.max(np.abs(reference[s]))) + absolute) for s, d in deviation.items())


def compared_signals(ssp: Union[str, Path]) -> dict[str, str]:
    """The signals compared between a host and the project's master for the system ``ssp`` (a built .ssp or an
    .ssd), with the unit its SSD gives each: the mechanism's pose components the pose command drives (every
    ``<c>_cmd`` input of the controller: the 3PRS's z, psi, theta, a hexapod's six), then every drive k's
    ``actuator_k.rho`` and ``actuator_k.i_m`` and ``mechanism.F_k``."""
    path = Path(ssp)
    if path.suffix == ".ssp":
        with zipfile.ZipFile(path) as archive:
            document = ssd.read(archive.read("SystemStructure.ssd"), origin=f"{path} (entry SystemStructure.ssd)")
    else:
        document = ssd.read(path)
    connectors = {(e.name, c.name): c.unit for e in document.system.elements for c in e.connectors}
    missing = [n for n in ("controller", "mechanism") if not any(e == n for e, _ in connectors)]
    if missing:
        raise ValueError(f"{ssp}: no component {' or '.join(missing)}: expected a system of the MAST's layout")
    pose = [c[: -len("_cmd")] for e, c in connectors if e == "controller" and c.endswith("_cmd") and c[:-4] in POSE]
    drives = sorted(
        (int(e.rpartition("_")[2]) for e, c in connectors if e.startswith("actuator_") and c == "rho"),
    )
    names = (
        [("mechanism", c) for c in pose]
        + [(f"actuator_{k}", "rho") for k in drives]
        + [(f"actuator_{k}", "i_m") for k in drives]
        + [("mechanism", f"F_{k}") for k in drives]
    )
    absent = [f"{e}.{c}" for e, c in names if (e, c) not in connectors]
    if absent or not pose or not drives:
        raise ValueError(
            f"{ssp}: signals {', '.join(absent) or 'of the pose and the drives'} are not in the system: expected "
            "a controller with pose commands <c>_cmd, actuator_k with rho and i_m, a mechanism with F_k and the pose"
        )
    return {f"{e}.{c}": connectors[e, c] for e, c in names}


def deviations(host: Result, reference: Result, signals: Sequence[str]) -> dict[str, float]:
    """Largest |host - reference| of each signal over the samples both have (matched by time)."""
    index = np.searchsorted(reference.time, host.time - 1e-9)
    ok = index < len(reference.time)
    ok[ok] &= np.abs(reference.time[index[ok]] - host.time[ok]) < 1e-9
    if not ok.any():
        raise ValueError("the host's samples and the reference's share no time")
    return {s: float(np.max(np.abs(host[s][ok] - reference[s][index[ok]]))) for s in signals}


def cross_check(
    ssp: Union[str, Path],
    stop_time: float,
    hosts: Sequence[str] = HOSTS,
    signals: Optional[Sequence[str]] = None,
    log=print,
) -> list[dict]:
    """Run ``ssp`` in the project's master and in each host; one row per host (deviations, the signals out of
    agreement, times).

    A host that cannot run here gets a row with its reason and no deviations.
    """
    import time

    from ..core.run import default_signals, simulate

    if signals is None:  # every signal the system records by default
        with SSPArchive(ssp) as archive:
            signals = comparable(default_signals(archive.system))
    signals = list(signals)
    wall = time.perf_counter()
    reference = simulate(ssp, None, stop_time, record=signals)
    rows = [{"host": "mast (reference)", "wall_time_s": time.perf_counter() - wall}]
    log(f"mast (this master, the reference): {rows[0]['wall_time_s']:.1f} s for {stop_time:g} s simulated")
    for host in hosts:
        reason = availability(host)
        if reason:
            rows.append({"host": host, "skipped": reason})
            log(f"{host}: skipped: {reason}")
            continue
        wall = time.perf_counter()
        result = run_host(host, ssp, stop_time, signals)
        absolute = PRINTED if host == "ecos" else ABSOLUTE
        row = {
            "host": host,
            "wall_time_s": time.perf_counter() - wall,
            "deviation": deviations(result, reference, signals),
        }
        row["failed"] = out_of_agreement(row["deviation"], reference, absolute)
        rows.append(row)
        used = agreement_used(row["deviation"], reference, absolute)
        log(
            f"{host}: {row['wall_time_s']:.1f} s; largest deviation {used:.2g}"
            f" of the agreement ({RELATIVE:g} of the signal's largest magnitude + {absolute:g}) over {len(signals)} "
            "signals"
            + (f"; OUT OF AGREEMENT: {', '.join(row['failed'])}" if row["failed"] else "")
            + (f"; {result.stats['exit_signal']} after the run" if "exit_signal" in result.stats else "")
        )
    return rows


# -- ecos command line: CSV configuration and output --------------------------------------
def _write_ecos_csv_config(path: Path, signals: Sequence[str], decimation: int) -> None:
    by_component: dict[str, list[str]] = {}
    for s in signals:
        element, _, connector = s.rpartition(".")
        if not element:
            raise ValueError(f"signal '{s}': expected element.connector")
        by_component.setdefault(element, []).append(connector)
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        '<ecos:CsvConfig xmlns:ecos="http://github.com/Ecos-platform/libecos/resources/schema/CsvConfig" '
        f'decimationFactor="{decimation}">',
        "  <ecos:components>",
    ]
    for element, connectors in by_component.items():
        lines.append(
            f'    <ecos:component name="{element}">'
            + "".join(f'<ecos:variable name="{c}"/>' for c in connectors)
            + "</ecos:component>"
        )
    lines += ["  </ecos:components>", "</ecos:CsvConfig>", ""]
    path.write_text("\n".join(lines), encoding="utf-8")


def _read_ecos_csv(path: Path, signals: Sequence[str]) -> Result:
    """ecos writes 'iterations, time, element::connector[REAL], ...' with 6 decimals."""
    with open(path, encoding="utf-8") as handle:
        header = [h.strip() for h in handle.readline().split(",")]
    table = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    columns = {h.split("[")[0].replace("::", "."): j for j, h in enumerate(header)}
    missing = [s for s in signals if s not in columns]
    if missing:
        raise HostError(f"ecos: {path.name} has no column for {', '.join(missing)} (header: {', '.join(header)})")
    return Result(
        table[:, columns["time"]].copy(), {s: table[:, columns[s]].copy() for s in signals}, stats={"decimals": 6}
    )


# -- the child processes ---------------------------------------------------------------------
def _child_libcosim(ssp: Path, stop_time: float, signals: Sequence[str], sample_step: float) -> Result:
    from libcosimpy._internal import get_last_error_message
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.WARNING)
    try:
        execution = CosimExecution.from_ssp_file(ssp_path=str(ssp))
    except AssertionError:
        raise HostError(f"libcosim cannot load {ssp.name}: {get_last_error_message()}") from None
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    slaves = {s.name.decode(): s.index for s in execution.slave_infos()}
    paths = []
    for s in signals:
        element, _, connector = s.rpartition(".")
        if element not in slaves:
            raise HostError(f"libcosim: no component '{element}' (components: {', '.join(sorted(slaves))})")
        refs = {v.name.decode(): v.reference for v in execution.slave_variables(slaves[element])}
        if connector not in refs:
            raise HostError(f"libcosim: component '{element}' has no variable '{connector}'")
        paths.append((slaves[element], refs[connector]))
    m = _decimation(sample_step, _base_step(ssp))
    n_samples = round(stop_time / sample_step)
    times, rows = [], []
    for _ in range(n_samples):
        if not execution.step(m):
            raise HostError(
                f"libcosim: step failed at t={execution.status().current_time * 1e-9:.6g} s: {get_last_error_message()}"
            )
        times.append(execution.status().current_time * 1e-9)
        rows.append([observer.last_real_values(index, [ref])[0] for index, ref in paths])
    data = np.array(rows).reshape(len(rows), len(paths))
    print(THREADS_LINE, len(os.listdir("/proc/self/task")), file=sys.stderr)
    return Result(np.array(times), {s: data[:, j].copy() for j, s in enumerate(signals)})


def _child_ecospy(ssp: Path, stop_time: float, signals: Sequence[str], sample_step: float) -> Result:
    ecospy = import_ecospy()
    EcosLib, EcosSimulation = ecospy.EcosLib, ecospy.EcosSimulation

    EcosLib.set_log_level("warn")
    base_step = _base_step(ssp)
    m = _decimation(sample_step, base_step)
    try:
        sim = EcosSimulation(ssp_path=str(ssp), step_size=base_step)
    except Exception as err:
        raise HostError(f"ecos cannot load {ssp.name}: {err}") from None
    names = [s.replace(".", "::", 1) if "." in s else s for s in signals]
    try:
        if not sim.init(parameter_set=FLAT_SET_NAME):
            raise HostError(f"ecos: initialization failed: {EcosLib.get_last_error()}")
        times, rows = [], []
        for k in range(round(stop_time / sample_step) + 1):
            if k:
                sim.step(m)
            times.append(sim.get_time())
            rows.append([sim.get_real(n) for n in names])
        sim.terminate()
    finally:
        sim.free()
    data = np.array(rows).reshape(len(rows), len(names))
    return Result(np.array(times), {s: data[:, j].copy() for j, s in enumerate(signals)})


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m mast.hosts.cosim", description="run a built SSP in a third-party co-simulation host"
    )
    parser.add_argument("host", choices=("libcosim", "ecospy"))
    parser.add_argument("ssp")
    parser.add_argument("--stop-time", type=float, required=True)
    parser.add_argument("--sample-step", type=float, default=1e-3)
    parser.add_argument("--signal", action="append", required=True, metavar="ELEMENT.CONNECTOR")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    run = _child_libcosim if args.host == "libcosim" else _child_ecospy
    try:
        result = run(Path(args.ssp), args.stop_time, args.signal, args.sample_step)
    except HostError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    write_csv(result, Path(args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
